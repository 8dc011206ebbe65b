#include "firmware/links/octoprint_link.hpp"

#include <deque>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

#include "firmware/links/job_text.hpp"

namespace calbox::firmware {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// What Marlin said in a terminal log line, or nothing for what the box sent and plain "ok"s.
std::optional<std::string> received(const std::string& log_line) {
    if (log_line.rfind("Recv: ", 0) != 0) return std::nullopt;
    std::string text = log_line.substr(6);
    if (text == "ok" || text.rfind("ok ", 0) == 0 || text.rfind("busy:", 0) == 0)
        return std::nullopt;
    return text;
}

}  // namespace

struct OctoPrintSession {
    OctoPrintLink& link;
    const OctoPrintSettings& settings;
    std::unique_ptr<hal::WebSocket> socket;
    std::deque<std::string> logs;  // terminal lines read, not yet taken
    long markers = 0;

    hal::HttpResponse http(hal::HttpRequest request) {
        link.check_stop();
        if (settings.api_key.empty())
            throw LinkError("OctoPrint: no API key in " + settings.key_file +
                            " yet (`link key` on the console asks OctoPrint for one)");
        request.headers.emplace_back("X-Api-Key", settings.api_key);
        try {
            return link.http_client().request(settings.url, request, settings.reply_timeout);
        } catch (const hal::NetworkError& e) {
            socket.reset();
            throw LinkError(std::string("OctoPrint: ") + e.what());
        }
    }

    static void refused_key(const hal::HttpResponse& r) {
        if (r.status == 401 || r.status == 403)
            throw LinkError("OctoPrint: the host refused the API key (" + http_error_line(r) +
                            "; is key_file's key one of its application keys?)");
    }

    // The push socket, authenticated with a passive login's session.
    void connect() {
        if (socket) return;
        const auto login =
            http({"POST", "/api/login", {}, "application/json", json{{"passive", true}}.dump()});
        refused_key(login);
        if (login.status != 200) throw LinkError("OctoPrint: login: " + http_error_line(login));
        const json user = json::parse(login.body, nullptr, false);
        if (user.is_discarded() || !user.contains("name") || !user.contains("session"))
            throw LinkError("OctoPrint: login: no session in the host's reply");
        net::Url url = settings.url;
        url.path = "/sockjs/websocket";
        try {
            socket = link.http_client().open_socket(url, hal::Headers{}, settings.reply_timeout);
            socket->send(json{{"auth", user["name"].get<std::string>() + ":" +
                                           user["session"].get<std::string>()}}
                             .dump());
        } catch (const hal::NetworkError& e) {
            socket.reset();
            throw LinkError(std::string("OctoPrint: ") + e.what());
        }
    }

    // Reads what the socket has within `within` into `logs`; false when nothing came.
    bool read_logs(std::chrono::milliseconds within) {
        std::optional<std::string> message;
        try {
            message = socket->receive(within);
        } catch (const hal::NetworkError& e) {
            socket.reset();
            throw LinkError(std::string("OctoPrint: ") + e.what());
        }
        if (!message) return false;
        const json j = json::parse(*message, nullptr, false);
        if (j.is_discarded() || !j.is_object()) return true;
        for (const char* kind : {"current", "history"})
            if (j.contains(kind) && j[kind].contains("logs") && j[kind]["logs"].is_array())
                for (const auto& line : j[kind]["logs"])
                    if (line.is_string()) logs.push_back(line.get<std::string>());
        return true;
    }

    // The commands bracketed by two echoed markers: what the printer said between them.
    std::vector<std::string> command(const std::vector<std::string>& lines) {
        connect();
        const std::string tag = "calbox-" + std::to_string(++markers);
        const std::string begin = tag + "-begin", end = tag + "-end";
        json commands = json::array({"M118 " + begin});
        for (const auto& line : lines) commands.push_back(line);
        commands.push_back("M118 " + end);
        const auto r = http({"POST",
                             "/api/printer/command",
                             {},
                             "application/json",
                             json{{"commands", commands}}.dump()});
        refused_key(r);
        if (r.status == 409)
            throw LinkError("OctoPrint: the printer is not operational (" + http_error_line(r) +
                            ")");
        if (r.status != 204 && r.status != 200)
            throw LinkError("OctoPrint: the host refused the commands (" + http_error_line(r) +
                            ")");
        std::vector<std::string> replies;
        bool inside = false;
        auto deadline = Clock::now() + settings.reply_timeout;
        for (;;) {
            while (!logs.empty()) {
                const auto text = received(logs.front());
                logs.pop_front();
                deadline = Clock::now() + settings.reply_timeout;  // the printer is talking
                if (!text) continue;
                if (*text == begin) {
                    inside = true;
                } else if (*text == end && inside) {
                    return replies;
                } else if (inside) {
                    if (text->rfind("Error:", 0) == 0) throw LinkError("the printer: " + *text);
                    replies.push_back(*text);
                }
            }
            link.check_stop();
            const auto left =
                std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
            if (left.count() <= 0)
                throw LinkError("OctoPrint: no reply from the printer within " +
                                std::to_string(settings.reply_timeout.count() / 1000) + " s");
            read_logs(std::min(left, std::chrono::milliseconds(100)));
        }
    }
};

template class HttpSessionLink<OctoPrintSettings, OctoPrintSession>;

OctoPrintLink::OctoPrintLink(OctoPrintSettings settings, hal::HttpClient& http, Log log)
    : HttpSessionLink("octoprint", std::move(settings), http, std::move(log)) {
    session_ =
        std::make_unique<OctoPrintSession>(OctoPrintSession{*this, settings_, nullptr, {}, 0});
}

OctoPrintLink::~OctoPrintLink() {
    finish_requests();
}

OctoPrintLink::PrintReport OctoPrintLink::job_report(const std::string& api_job_body,
                                                     const std::string& ours_name, bool seen) {
    const json job = json::parse(api_job_body, nullptr, false);
    if (job.is_discarded() || !job.is_object()) throw LinkError("OctoPrint: /api/job: not JSON");
    PrintReport report;
    report.state = job.value("state", std::string());
    const std::string& state = report.state;
    // Read by pointer: a const object's operator[] on a key a host left out is undefined.
    const json name = job.value(json::json_pointer("/job/file/name"), json());
    const bool ours = name.is_string() && name == ours_name;
    const json completion = job.value(json::json_pointer("/progress/completion"), json());
    const double percent = completion.is_number() ? completion.get<double>() : 0.0;
    if (state.rfind("Error", 0) == 0 || state.rfind("Offline", 0) == 0)
        throw LinkError("the print failed on the host: " + state);
    // Idle again part of the way through: stopped on the host.
    const bool stopped_part_way =
        state == "Operational" && ours && percent < 100 && (seen || percent > 0);
    if (state == "Cancelling" || stopped_part_way)
        report.over = JobOutcome{false, "the print was cancelled on the host", {}, {}};
    else if (state == "Operational" && ours && percent >= 100)
        report.over = JobOutcome{true, {}, {}, {}};
    report.printing = state == "Printing" || state == "Paused" || state == "Pausing" ||
                      state == "Resuming" || state == "Starting";
    return report;
}

void OctoPrintLink::run_job(const std::vector<std::string>& lines, Done done) {
    std::string text = joined(lines);
    start_in_session(
        [this, text = std::move(text)](OctoPrintSession& s) {
            const auto form = net::multipart_form("file", settings_.job_file_name, text,
                                                  {{"select", "true"}, {"print", "true"}});
            const auto up = s.http({"POST", "/api/files/local", {}, form.content_type, form.body});
            OctoPrintSession::refused_key(up);
            if (up.status != 201 && up.status != 200)
                throw LinkError("the host refused the upload of " + settings_.job_file_name + " (" +
                                http_error_line(up) + ")");
            return follow_print(settings_.poll_interval, settings_.reply_timeout, [&](bool seen) {
                const auto r = s.http({"GET", "/api/job", {}, {}, {}});
                OctoPrintSession::refused_key(r);
                if (r.status != 200) throw LinkError("OctoPrint: /api/job: " + http_error_line(r));
                return job_report(r.body, settings_.job_file_name, seen);
            });
        },
        std::move(done));
}

std::string request_octoprint_key(hal::HttpClient& http, const net::Url& url,
                                  const std::string& user, std::chrono::milliseconds wait,
                                  const hal::Log& log) {
    const auto timeout = std::chrono::milliseconds(10000);
    json request = {{"app", "calbox"}};
    if (!user.empty()) request["user"] = user;
    hal::HttpResponse r;
    try {
        r = http.request(
            url, {"POST", "/plugin/appkeys/request", {}, "application/json", request.dump()},
            timeout);
    } catch (const hal::NetworkError& e) {
        throw LinkError(std::string("OctoPrint: ") + e.what());
    }
    if (r.status == 404)
        throw LinkError("OctoPrint: the host has no application keys plugin (HTTP 404)");
    if (r.status != 201) throw LinkError("OctoPrint: asking for a key: " + http_error_line(r));
    const json token = json::parse(r.body, nullptr, false);
    if (token.is_discarded() || !token.contains("app_token"))
        throw LinkError("OctoPrint: asking for a key: no app_token in the reply");
    const std::string path = "/plugin/appkeys/request/" + token["app_token"].get<std::string>();
    log.warning("OctoPrint at " + url.origin() + ": allow calbox's access in OctoPrint's page");
    const auto until = Clock::now() + wait;
    while (Clock::now() < until) {
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
        try {
            r = http.request(url, {"GET", path, {}, {}, {}}, timeout);
        } catch (const hal::NetworkError& e) {
            throw LinkError(std::string("OctoPrint: ") + e.what());
        }
        if (r.status == 202) continue;
        if (r.status == 404) throw LinkError("OctoPrint: the owner denied calbox's access");
        const json key = json::parse(r.body, nullptr, false);
        if (r.status == 200 && !key.is_discarded() && key.contains("api_key") &&
            key["api_key"].is_string())
            return key["api_key"].get<std::string>();
        throw LinkError("OctoPrint: waiting for the key: " + http_error_line(r));
    }
    throw LinkError("OctoPrint: nobody allowed calbox's access within " +
                    std::to_string(std::chrono::duration_cast<std::chrono::seconds>(wait).count()) +
                    " s");
}

}  // namespace calbox::firmware
