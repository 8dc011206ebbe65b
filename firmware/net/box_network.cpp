#include "firmware/net/box_network.hpp"

#include <nlohmann/json.hpp>

#include "core/geometry/camera_model.hpp"
#include "firmware/cycle/screens.hpp"
#include "firmware/net/mqtt_report.hpp"
#include "firmware/net/web_tls.hpp"
#include "firmware/net/web_window.hpp"

namespace calbox::firmware {
namespace {

using json = nlohmann::json;

// "http://[::1]:8080/": an IPv6 address in brackets.
std::string url_of(const char* scheme, const std::string& host, int port) {
    const std::string shown = host.find(':') != std::string::npos ? "[" + host + "]" : host;
    return std::string(scheme) + "://" + shown + ":" + std::to_string(port) + "/";
}

// What the page's log and plot show at most; /api/history has every line kept.
constexpr std::size_t kPageLogLines = 40;
constexpr std::size_t kPageHistory = 100;

}  // namespace

BoxNetwork::BoxNetwork(BoxNetworkParts parts) : BoxNetwork(std::move(parts), WebLimits{}) {}

BoxNetwork::BoxNetwork(BoxNetworkParts parts, const WebLimits& limits)
    : p_(std::move(parts)), inbox_(p_.loop) {
    const bool tls = !p_.web.tls_listen.empty();
    const std::string page_at = tls ? p_.web.tls_listen : p_.web.listen;
    if (!page_at.empty()) {
        if (tls)
            tls_ = web_tls_identity(p_.web, p_.data_dir, p_.network.certificates(), p_.unix_now(),
                                    p_.log);
        const auto at = net::parse_host_port(page_at, false);
        web_ = std::make_unique<WebWindow>(
            WebWindowContext{
                inbox_, p_.data, p_.clock, frames_, p_.network, p_.cycle.mode().kept_files(),
                [this](const std::string& line) { return p_.console.reply_to(line); },
                [this] { return status(true); }, [this] { return p_.news.history_json(); },
                [this] { return p_.news.metrics(p_.cycle); },
                [this] { return p_.web.password_hash; }, [this] { return p_.cycle.preview(); },
                [this] { return guide(); }, [this] { return p_.cycle.mode().kept_result_text(); }},
            at.host, at.port, limits, tls_ ? std::optional(tls_->files) : std::nullopt);
        p_.log("web: the page at " + url_of(tls_ ? "https" : "http", at.host, web_->port()) +
               (tls_ ? " (certificate " + tls_->facts.subject + ", SHA-256 " +
                           tls_->facts.sha256_fingerprint + ")"
                     : std::string()) +
               (p_.web.password_hash.empty()
                    ? " (no web password: it changes nothing until the console's `web password`)"
                    : ""));
    }
    if (tls && !p_.web.listen.empty()) {
        const auto at = net::parse_host_port(p_.web.listen, false);
        const int https_port = web_->port();
        redirect_ =
            p_.network.listen(at.host, at.port,
                              hal::HttpHandlers{[https_port](const hal::ServerRequest& r) {
                                                    return plain_port_answer(r, https_port);
                                                },
                                                [](const hal::ServerRequest&) { return 403; },
                                                [](const hal::ServerRequest&, const std::string&) {
                                                    return std::vector<std::string>{};
                                                }},
                              server_limits(limits), std::nullopt);
        p_.log("web: " + url_of("http", at.host, redirect_->port()) +
               " only sends browsers on to https, and never takes the password");
    }
    p_.console.add_rows({web_tls_row()});
    if (!p_.mqtt.broker.empty()) {
        // A login that cannot be tried (the password's file open to others) leaves MQTT off and
        // says why: the box still calibrates.
        try {
            mqtt_ = std::make_unique<MqttReport>(
                MqttReport::Context{
                    inbox_, [this] { return status(false); },
                    [this](const std::string& line) { return p_.console.reply_to(line); }, p_.log,
                    p_.version, p_.network},
                p_.mqtt);
        } catch (const std::runtime_error& e) {
            p_.log.error(std::string("mqtt: off: ") + e.what());
        }
    }
    CycleNews news{[this](Prompt, int) { changed(); },
                   [this](CycleState) { changed(); },
                   [this](bool completed) { cycle_ended(completed); },
                   {},
                   {}};
    if (web_) news.frame = [this](const hal::Frame& frame) { frames_.put(frame); };
    listening_ = p_.cycle.subscribe(std::move(news));
}

BoxNetwork::~BoxNetwork() {
    // The servers' threads first: they post to the inbox and read the frames.
    redirect_.reset();
    web_.reset();
    mqtt_.reset();
}

int BoxNetwork::web_port() const {
    return web_ ? web_->port() : 0;
}

ConsoleCommand BoxNetwork::web_tls_row() {
    return {"web tls", "web tls",
            "the page's https port and its certificate's SHA-256 fingerprint (also on the "
            "display), to check a browser's warning against",
            [this](const std::vector<std::string>& words, std::string_view, ConsoleReply& r) {
                need_words(words, 2, "web tls");
                if (!tls_) {
                    r.text =
                        "web tls: off (web.tls_listen is empty): the page, if any, is plain "
                        "http";
                    r.data = {{"tls", false}};
                    return;
                }
                const auto& f = tls_->facts;
                const int port = web_->port();
                r.text =
                    "web tls: https on port " + std::to_string(port) + "; certificate " +
                    f.subject +
                    (tls_->self_signed ? " (the box's own, self-signed, " : " (the owner's, ") +
                    tls_->files.certificate_file + "), valid until " +
                    utc_text(f.not_after_unix_s) + "\nSHA-256 " + f.sha256_fingerprint;
                r.data = {{"tls", true},
                          {"port", port},
                          {"sha256", f.sha256_fingerprint},
                          {"self_signed", tls_->self_signed},
                          {"certificate_file", tls_->files.certificate_file},
                          {"not_after", utc_text(f.not_after_unix_s)}};
                p_.cycle.show_aside(
                    draw_screen(NetworkScreen{port, fingerprint_lines(f.sha256_fingerprint)}));
            }};
}

json BoxNetwork::status(bool for_page) const {
    json j = p_.news.status(p_.cycle);
    if (!for_page) return j;
    j["log"] = p_.log_book.last(kPageLogLines);
    // Built on every status push (each log line): only the lines the page plots.
    j["history"] = p_.news.history_json(kPageHistory)["cycles"];
    return j;
}

void BoxNetwork::changed() {
    if (web_) web_->push(json{{"type", "status"}, {"status", status(true)}}.dump());
    if (mqtt_) mqtt_->publish_status(status(false));
}

void BoxNetwork::logged() {
    if (web_) web_->push(json{{"type", "status"}, {"status", status(true)}}.dump());
}

void BoxNetwork::cycle_ended(bool completed) {
    if (const auto why = p_.news.cycle_ended(p_.cycle, completed, p_.unix_now()); !why.empty())
        p_.log.warning(why);
    if (mqtt_ && !p_.news.history().empty())
        mqtt_->publish_result(p_.news.history_json(1)["cycles"].back());
    changed();
}

LiveGuide BoxNetwork::guide() const {
    LiveGuide g;
    // A set-up file that does not read leaves the outline off; the cycle says why when it runs.
    try {
        if (const auto camera = p_.data.read_file("camera.yaml"))
            g.camera = geometry::camera_from_yaml(*camera);
        if (const auto plane = p_.data.read_file("plane.yaml"))
            g.plane = geometry::plane_from_yaml(*plane);
    } catch (const std::exception&) {
        g.camera.reset();
        g.plane.reset();
    }
    const models::MachineFile& machine = p_.cycle.machine();
    if (machine.is_delta()) {  // a round bed
        g.bed_radius_mm = machine.bed_radius_mm;
    } else {
        g.bed_size_x_mm = machine.bed_size_x_mm;
        g.bed_size_y_mm = machine.bed_size_y_mm;
    }
    for (const auto& view : p_.cycle.setup_views()) {
        std::vector<geometry::Point2> corners(view.board.image_points.begin(),
                                              view.board.image_points.end());
        g.views.push_back(std::move(corners));
    }
    g.coverage = p_.cycle.setup_coverage();
    return g;
}

}  // namespace calbox::firmware
