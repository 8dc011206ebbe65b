#include "firmware/console/link_key.hpp"

#include <filesystem>

#include "firmware/links/octoprint_link.hpp"
#include "firmware/loop/event_loop.hpp"

namespace calbox::firmware {

LinkKeyRequest::LinkKeyRequest(EventLoop& loop, models::MachineLinkSettings link,
                               hal::HttpClient& http, OpenKeyDirectory open_key_directory,
                               Notice notice)
    : loop_(loop),
      link_(std::move(link)),
      http_(http),
      open_key_directory_(std::move(open_key_directory)),
      notice_(std::move(notice)) {
    loop_.watch(request_.fd(), [this] { finished(); });
}

LinkKeyRequest::~LinkKeyRequest() {
    loop_.unwatch(request_.fd());
}

ConsoleCommand LinkKeyRequest::command() {
    return {
        "link key", "link key [USER]",
        "ask OctoPrint for an API key for the box (allow it in OctoPrint's page); kept in "
        "link.key_file",
        [this](const std::vector<std::string>& words, std::string_view, ConsoleReply& reply) {
            if (link_.kind != "octoprint")
                throw ConsoleRefused(
                    "link key: keys are asked of OctoPrint; this machine's "
                    "link is " +
                    link_.kind);
            if (link_.key_file.empty())
                throw ConsoleRefused("link key: set link.key_file (where the key is kept) first");
            if (words.size() > 3) throw ConsoleRefused("link key takes one user name at most");
            if (request_.busy()) throw ConsoleRefused("link key: already waiting for OctoPrint");
            net::Url url;
            try {
                url = net::parse_url(link_.url);
            } catch (const std::invalid_argument& e) {
                throw ConsoleRefused(std::string("link key: ") + e.what());
            }
            const std::string user = words.size() == 3 ? words[2] : std::string();
            request_.start([this, url, user] {
                try {
                    return std::pair<bool, std::string>{
                        true, request_octoprint_key(http_, url, user, std::chrono::minutes(5),
                                                    [](const std::string&) {})};
                } catch (const std::exception& e) {
                    return std::pair<bool, std::string>{false, e.what()};
                }
            });
            reply.text = "asking OctoPrint at " + url.origin() +
                         " for a key: allow calbox in OctoPrint's page";
            reply.data = {{"asked", url.origin()}};
        }};
}

void LinkKeyRequest::finished() {
    auto result = request_.take();
    if (!result) return;
    if (!result->first) {
        notice_("link key: " + result->second);
        return;
    }
    try {
        open_key_directory_()->replace_private_file(
            std::filesystem::path(link_.key_file).filename(), result->second + "\n");
    } catch (const std::exception& e) {
        notice_("link key: OctoPrint gave a key, but it could not be kept: " +
                std::string(e.what()));
        return;
    }
    notice_("link key: OctoPrint's key for calbox is in " + link_.key_file +
            "; the box uses it from its next start");
}

}  // namespace calbox::firmware
