#include "firmware/links/moonraker_link.hpp"

#include <cstdio>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>

#include "firmware/links/job_text.hpp"
#include "firmware/loop/event_loop.hpp"

namespace calbox::firmware {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// A value of configfile.settings as printer.cfg writes it.
std::string config_value(const json& v) {
    if (v.is_string()) return v.get<std::string>();
    if (v.is_boolean()) return v.get<bool>() ? "True" : "False";
    if (v.is_number()) {
        char b[40];
        std::snprintf(b, sizeof b, "%.10g", v.get<double>());
        return b;
    }
    return {};
}

}  // namespace

struct MoonrakerSession {
    const MoonrakerLink& link;
    const MoonrakerSettings& settings;
    std::unique_ptr<hal::WebSocket> socket;
    long next_id = 1;

    hal::Headers auth() const {
        if (settings.api_key.empty()) return {};
        return {{"X-Api-Key", settings.api_key}};
    }

    void check_stop() const { link.check_stop(); }

    void connect() {
        if (socket) return;
        net::Url url = settings.url;
        url.path = "/websocket";
        try {
            // The key goes with HTTP requests only: the long-lived socket is opened with a
            // one-shot token the key fetches (single use, valid seconds), as Moonraker's web
            // clients do. A host that trusts the box needs neither.
            if (!settings.api_key.empty()) url.path += "?token=" + oneshot_token();
            socket = link.http_client().open_socket(url, hal::Headers{}, settings.reply_timeout);
        } catch (const hal::NetworkError& e) {
            throw LinkError(std::string("Moonraker: ") + e.what() +
                            (std::string(e.what()).find("HTTP 401") != std::string::npos
                                 ? " (is key_file's API key the host's?)"
                                 : ""));
        }
        call("server.connection.identify", {{"client_name", "calbox"},
                                            {"version", "1"},
                                            {"type", "other"},
                                            {"url", "https://calbox.invalid"}});
    }

    // A JSON-RPC request and its result; the G-code responses that arrive meanwhile are added
    // to `responses`.
    // The result when `message` answers request `id` (nothing for another message: a
    // notification, whose G-code responses are kept in `responses`, or another's answer);
    // throws LinkError for the request's error.
    static std::optional<json> answer_to(const std::string& message, long id,
                                         const std::string& method,
                                         std::vector<std::string>* responses) {
        const json j = json::parse(message, nullptr, false);
        if (j.is_discarded() || !j.is_object()) return std::nullopt;
        if (j.contains("method")) {
            if (responses != nullptr && j["method"] == "notify_gcode_response" &&
                j.contains("params") && j["params"].is_array())
                for (const auto& p : j["params"])
                    if (p.is_string()) responses->push_back(p.get<std::string>());
            return std::nullopt;
        }
        if (!j.contains("id") || j["id"] != id) return std::nullopt;
        if (j.contains("error")) {
            const auto& e = j["error"];
            throw LinkError(method + ": " +
                            (e.contains("message") && e["message"].is_string()
                                 ? e["message"].get<std::string>()
                                 : e.dump()));
        }
        return j.contains("result") ? j["result"] : json();
    }
    json call(const std::string& method, const json& params,
              std::vector<std::string>* responses = nullptr) {
        check_stop();
        connect();
        const long id = next_id++;
        try {
            socket->send(json{
                {"jsonrpc", "2.0"},
                {"method", method},
                {"params", params},
                {"id", id}}.dump());
            const auto deadline = Clock::now() + settings.reply_timeout;
            for (;;) {
                check_stop();
                const auto left =
                    std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
                if (left.count() <= 0)
                    throw LinkError("Moonraker: no reply to " + method + " within " +
                                    std::to_string(settings.reply_timeout.count() / 1000) + " s");
                const auto message =
                    socket->receive(std::min(left, std::chrono::milliseconds(100)));
                if (!message) continue;
                if (auto answer = answer_to(*message, id, method, responses)) return *answer;
            }
        } catch (const hal::NetworkError& e) {
            socket.reset();  // the next request connects again
            throw LinkError(std::string("Moonraker: ") + e.what());
        }
    }

    hal::HttpResponse http(hal::HttpRequest request) {
        check_stop();
        for (auto& h : auth()) request.headers.push_back(std::move(h));
        try {
            return link.http_client().request(settings.url, request, settings.reply_timeout);
        } catch (const hal::NetworkError& e) {
            throw LinkError(std::string("Moonraker: ") + e.what());
        }
    }

    std::string oneshot_token() {
        const auto r = http({"GET", "/access/oneshot_token", {}, {}, {}});
        const json j = json::parse(r.body, nullptr, false);
        if (r.status != 200 || j.is_discarded() || !j.contains("result") ||
            !j["result"].is_string())
            throw LinkError("Moonraker: /access/oneshot_token: " + http_error_line(r) +
                            (r.status == 401 ? " (is key_file's API key the host's?)" : ""));
        return j["result"].get<std::string>();
    }

    std::string klippy_state(std::string* message = nullptr) {
        const json info = call("printer.info", json::object());
        if (message != nullptr) *message = config_value(info.value("state_message", json("")));
        return config_value(info.value("state", json("")));
    }

    void ensure_ready() {
        std::string message;
        const std::string state = klippy_state(&message);
        if (state != "ready")
            throw LinkError("Klipper is not ready (" + state +
                            (message.empty() ? std::string() : ": " + message) + ")");
    }

    // One script per line: each has its own deadline; what Klipper said, in order.
    std::vector<std::string> command(const std::vector<std::string>& lines) {
        ensure_ready();
        std::vector<std::string> replies;
        for (const auto& line : lines) call("printer.gcode.script", {{"script", line}}, &replies);
        return replies;
    }

    void upload(const std::string& root, const std::string& name, const std::string& contents) {
        const auto form = net::multipart_form("file", name, contents, {{"root", root}});
        const auto r = http({"POST", "/server/files/upload", {}, form.content_type, form.body});
        if (r.status != 200 && r.status != 201)
            throw LinkError("the host refused the upload of " + name + " (" + http_error_line(r) +
                            ")");
    }

    std::string download(const std::string& path) {
        const auto r = http({"GET", "/server/files/" + path, {}, {}, {}});
        if (r.status != 200)
            throw LinkError("reading " + path + " from the host: " + http_error_line(r));
        return r.body;
    }

    void pause() const { link.pause(settings.poll_interval); }

    // After a restart `what` asked for: ready again, or the reason Klipper gives for not
    // starting with `taking`.
    void await_ready(const std::string& what, const std::string& taking) {
        const auto deadline = Clock::now() + settings.restart_timeout;
        std::string state, message;
        while (Clock::now() < deadline) {
            pause();
            try {
                state = klippy_state(&message);
            } catch (const LinkError&) {
                state = "restarting";  // the host reconnects to Klipper meanwhile
                continue;
            }
            if (state == "ready") return;
            if (state == "error" || state == "shutdown")
                throw LinkError("Klipper did not start with " + taking + " (" +
                                state.append(": ").append(message) + ")");
        }
        throw LinkError("Klipper was not ready within " +
                        std::to_string(settings.restart_timeout.count() / 1000) + " s of " + what +
                        " (" + state + ")");
    }
};

template class HttpSessionLink<MoonrakerSettings, MoonrakerSession>;

MoonrakerLink::MoonrakerLink(MoonrakerSettings settings, hal::HttpClient& http, Log log)
    : HttpSessionLink("moonraker", std::move(settings), http, std::move(log)) {
    session_ = std::make_unique<MoonrakerSession>(MoonrakerSession{*this, settings_, nullptr, 1});
}

MoonrakerLink::~MoonrakerLink() {
    finish_requests();
}

void MoonrakerLink::run_job(const std::vector<std::string>& lines, Done done) {
    start_in_session(
        [this, text = joined(lines)](MoonrakerSession& s) {
            s.ensure_ready();
            s.upload("gcodes", settings_.job_file_name, text);
            s.call("printer.print.start", {{"filename", settings_.job_file_name}});
            const json query = {{"objects", {{"print_stats", {"state", "message"}}}}};
            return follow_print(settings_.poll_interval, settings_.reply_timeout, [&](bool) {
                const json status = s.call("printer.objects.query", query);
                const json& stats = status.at("status").at("print_stats");
                PrintReport report;
                report.state = config_value(stats.value("state", json("")));
                const std::string& state = report.state;
                report.printing = state == "printing" || state == "paused";
                if (state == "complete")
                    report.over = JobOutcome{true, {}, {}, {}};
                else if (state == "cancelled")
                    report.over = JobOutcome{false, "the print was cancelled on the host", {}, {}};
                else if (state == "error")
                    report.over = JobOutcome{false,
                                             "the print failed on the host: " +
                                                 config_value(stats.value("message", json(""))),
                                             {},
                                             {}};
                else if (state == "standby")
                    report.over =
                        JobOutcome{false, "the print ended on the host without completing", {}, {}};
                return report;
            });
        },
        std::move(done));
}

void MoonrakerLink::read_config_file(Done done) {
    start_in_session(
        [](MoonrakerSession& s) {
            // The file API answers whatever Klipper's state (a printer.cfg it refused included).
            return JobOutcome{true, {}, {}, s.download("config/printer.cfg")};
        },
        std::move(done));
}

void MoonrakerLink::replace_config_file(const std::string& text, const std::string& expected_now,
                                        Done done) {
    start_in_session(
        [text, expected_now](MoonrakerSession& s) {
            if (s.download("config/printer.cfg") != expected_now)
                throw LinkError(
                    "printer.cfg was changed on the host since the box read it; nothing was "
                    "written");
            s.upload("config", "printer.cfg", text);
            s.call("printer.firmware_restart", json::object());
            s.await_ready("FIRMWARE_RESTART", "the new printer.cfg");
            return JobOutcome{true, {}, {}, {}};
        },
        std::move(done));
}

void MoonrakerLink::save_config_after(const std::vector<std::string>& lines, Done done) {
    start_in_session(
        [lines](MoonrakerSession& s) {
            JobOutcome outcome{true, {}, s.command(lines), {}};
            // Klipper writes printer.cfg and restarts: the script's reply may be lost with the
            // connection to klippy ("Klippy Disconnected", or none). A refusal is an error.
            try {
                s.call("printer.gcode.script", {{"script", "SAVE_CONFIG"}}, &outcome.replies);
            } catch (const LinkError& e) {
                const std::string why = e.what();
                if (why.find("isconnected") == std::string::npos &&
                    why.find("no reply") == std::string::npos && why.rfind("Moonraker:", 0) != 0)
                    throw;
            }
            s.await_ready("SAVE_CONFIG", "the saved printer.cfg");
            return outcome;
        },
        std::move(done));
}

void MoonrakerLink::read_settings_in_force(Done done) {
    start_in_session(
        [](MoonrakerSession& s) {
            s.ensure_ready();
            const json r =
                s.call("printer.objects.query", {{"objects", {{"configfile", {"settings"}}}}});
            const json& settings = r.at("status").at("configfile").at("settings");
            std::string text;
            for (const auto& [section, values] : settings.items()) {
                if (!values.is_object()) continue;
                text += "[" + section + "]\n";
                for (const auto& [key, value] : values.items())
                    if (value.is_primitive() && !value.is_null())
                        text += key + ": " + config_value(value) + "\n";
            }
            return JobOutcome{true, {}, {}, text};
        },
        std::move(done));
}

}  // namespace calbox::firmware
