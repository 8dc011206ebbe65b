#include "firmware/links/duet_link.hpp"

#include <boost/crc.hpp>
#include <cctype>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "firmware/links/job_text.hpp"

namespace calbox::firmware {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

}  // namespace

std::string url_encoded(const std::string& text) {
    std::string out;
    for (const unsigned char c : text) {
        if (std::isalnum(c) || c == '-' || c == '_' || c == '.' || c == '~') {
            out += static_cast<char>(c);
        } else {
            char b[4];
            std::snprintf(b, sizeof b, "%%%02X", c);
            out += b;
        }
    }
    return out;
}

struct DuetSession {
    DuetLink& link;
    const DuetSettings& settings;
    std::optional<std::string> session_key;
    long markers = 0;
    // A standalone board serves the rr_ requests; one with an SBC, DuetSoftwareFramework's
    // /machine API (as Duet Web Control finds out: rr_connect answered 404 there).
    bool sbc = false;

    hal::HttpResponse raw(hal::HttpRequest request) {
        link.check_stop();
        if (session_key) request.headers.emplace_back("X-Session-Key", *session_key);
        try {
            return link.http_client().request(settings.url, request, settings.reply_timeout);
        } catch (const hal::NetworkError& e) {
            session_key.reset();
            throw LinkError(std::string("Duet: ") + e.what());
        }
    }

    void connect() {
        if (session_key) return;
        if (!sbc && connect_standalone()) return;
        sbc = true;
        connect_sbc();
    }

    // rr_connect; false when the board answers 404 (it has an SBC: the /machine API).
    bool connect_standalone() {
        const auto r = raw({"GET",
                            "/rr_connect?password=" + url_encoded(settings.password) +
                                "&time=2026-01-01T00%3A00%3A00",
                            {},
                            {},
                            {}});
        if (r.status == 404) return false;
        const json j = json::parse(r.body, nullptr, false);
        if (r.status != 200 || !j.is_object() || !j.contains("err") || !j["err"].is_number())
            throw LinkError("Duet: rr_connect: HTTP " + std::to_string(r.status));
        const int err = j["err"].get<int>();
        if (err == 1) throw wrong_password();
        if (err == 2) throw LinkError("Duet: the board has no free session");
        if (err != 0) throw LinkError("Duet: rr_connect: err " + std::to_string(err));
        session_key = j.contains("sessionKey") ? j["sessionKey"].dump() : std::string("0");
        return true;
    }

    void connect_sbc() {
        const auto r =
            raw({"GET", "/machine/connect?password=" + url_encoded(settings.password), {}, {}, {}});
        if (r.status == 403) throw wrong_password();
        const json j = json::parse(r.body, nullptr, false);
        if (r.status != 200 || !j.is_object() || !j.contains("sessionKey"))
            throw LinkError("Duet: /machine/connect: HTTP " + std::to_string(r.status) +
                            (r.status == 502 || r.status == 503
                                 ? " (DuetControlServer is not running on the SBC)"
                                 : ""));
        session_key = j["sessionKey"].is_string() ? j["sessionKey"].get<std::string>()
                                                  : j["sessionKey"].dump();
    }

    static LinkError wrong_password() {
        return LinkError("Duet: the board refused the password (is key_file's the board's M551?)");
    }

    // The session closed when the box stops, so that the board's few sessions are not held until
    // they time out; best effort.
    void disconnect() noexcept {
        if (!session_key) return;
        try {
            hal::HttpRequest request{
                "GET", sbc ? "/machine/disconnect" : "/rr_disconnect", {}, {}, {}};
            request.headers.emplace_back("X-Session-Key", *session_key);
            link.http_client().request(settings.url, request, std::chrono::milliseconds(1000));
        } catch (const std::exception&) {
        }
        session_key.reset();
    }

    // A request in the session; one whose session expired (401) connects again, once.
    hal::HttpResponse call(const hal::HttpRequest& request) {
        connect();
        auto r = raw(request);
        if (r.status == 401 || (sbc && r.status == 403)) {
            session_key.reset();
            connect();
            r = raw(request);
        }
        if (r.status != 200 && r.status != 201)
            throw LinkError("Duet: " + request.target.substr(0, request.target.find('?')) +
                            ": HTTP " + std::to_string(r.status) +
                            (r.body.empty() || r.body.size() > 200 ? "" : " (" + r.body + ")"));
        return r;
    }

    json model(const std::string& key) {
        connect();  // which API the board serves
        if (sbc) {
            const json j =
                json::parse(call({"GET", "/machine/model", {}, {}, {}}).body, nullptr, false);
            if (j.is_discarded() || !j.contains(key))
                throw LinkError("Duet: /machine/model has no " + key);
            return j[key];
        }
        const auto r = call({"GET", "/rr_model?key=" + key + "&flags=d99f", {}, {}, {}});
        const json j = json::parse(r.body, nullptr, false);
        if (j.is_discarded() || !j.contains("result"))
            throw LinkError("Duet: rr_model " + key + ": no result");
        return j["result"];
    }

    // The job's file on the board's SD card (0:/gcodes/...), whole.
    void upload(const std::string& path, const std::string& text) {
        connect();
        if (sbc) {
            const auto r = raw({"PUT",
                                "/machine/file/" + url_encoded(path),
                                {},
                                "application/octet-stream",
                                text});
            if (r.status != 201 && r.status != 200)
                throw LinkError("the host refused the upload of " + settings.job_file_name +
                                " (/machine/file: HTTP " + std::to_string(r.status) +
                                (r.body.empty() || r.body.size() > 200 ? "" : ": " + r.body) + ")");
            return;
        }
        boost::crc_32_type crc;
        crc.process_bytes(text.data(), text.size());
        char crc_hex[16];
        std::snprintf(crc_hex, sizeof crc_hex, "%08x", crc.checksum());
        const auto up = call({"POST",
                              "/rr_upload?name=" + url_encoded(path) +
                                  "&time=2026-01-01T00%3A00%3A00&crc32=" + crc_hex,
                              {},
                              "application/octet-stream",
                              text});
        const json stored = json::parse(up.body, nullptr, false);
        const bool told_err = stored.is_object() && stored.contains("err");
        if (!told_err || stored["err"] != 0)
            throw LinkError("the host refused the upload of " + settings.job_file_name +
                            " (rr_upload: err " +
                            (told_err ? stored["err"].dump() : std::string("?")) + ")");
    }

    std::string status() { return model("state").value("status", std::string()); }

    void ensure_ready() {
        const std::string s = status();
        if (s == "off" || s == "halted" || s == "starting" || s == "updating")
            throw LinkError("RepRapFirmware is not ready (" + s + ")");
    }

    // DuetSoftwareFramework runs a code and answers with its reply.
    std::string sbc_code(const std::string& line) {
        return call({"POST", "/machine/code", {}, "text/plain", line}).body;
    }

    void gcode(const std::string& line) {
        connect();
        if (sbc) {
            const std::string reply = sbc_code(line);
            if (reply.rfind("Error:", 0) == 0) throw LinkError("the printer: " + reply);
            return;
        }
        const auto r = call({"GET", "/rr_gcode?gcode=" + url_encoded(line), {}, {}, {}});
        const json j = json::parse(r.body, nullptr, false);
        if (j.is_discarded() || j.value("err", 0) != 0)
            throw LinkError("Duet: the board did not take '" + line + "'");
    }

    // The lines, then a marker the firmware echoes: the replies up to the marker.
    std::vector<std::string> command(const std::vector<std::string>& lines) {
        ensure_ready();
        return sbc ? sbc_command(lines) : standalone_command(lines);
    }

    // A reply's lines, without their CR and the empty ones.
    static std::vector<std::string> reply_lines(const std::string& body) {
        std::vector<std::string> lines;
        std::istringstream text(body);
        for (std::string line; std::getline(text, line);) {
            if (!line.empty() && line.back() == '\r') line.pop_back();
            if (!line.empty()) lines.push_back(line);
        }
        return lines;
    }

    // DuetSoftwareFramework answers each code with its reply.
    std::vector<std::string> sbc_command(const std::vector<std::string>& lines) {
        std::vector<std::string> replies;
        for (const auto& line : lines)
            for (auto& reply : reply_lines(sbc_code(line))) {
                if (reply.rfind("Error:", 0) == 0) throw LinkError("the printer: " + reply);
                replies.push_back(std::move(reply));
            }
        return replies;
    }

    // A standalone board's replies come from rr_reply, polled until the marker's echo.
    std::vector<std::string> standalone_command(const std::vector<std::string>& lines) {
        const std::string end = "calbox-" + std::to_string(++markers) + "-end";
        for (const auto& line : lines) gcode(line);
        gcode("M118 S\"" + end + "\"");
        std::vector<std::string> replies;
        auto deadline = Clock::now() + settings.reply_timeout;
        for (;;) {
            for (auto& line : reply_lines(call({"GET", "/rr_reply", {}, {}, {}}).body)) {
                deadline = Clock::now() + settings.reply_timeout;
                if (line == end) return replies;
                if (line.rfind("Error:", 0) == 0) throw LinkError("the printer: " + line);
                replies.push_back(std::move(line));
            }
            if (Clock::now() > deadline)
                throw LinkError("Duet: no reply from the printer within " +
                                std::to_string(settings.reply_timeout.count() / 1000) + " s");
            link.pause(settings.poll_interval);
        }
    }
};

template class HttpSessionLink<DuetSettings, DuetSession>;

DuetLink::DuetLink(DuetSettings settings, hal::HttpClient& http, Log log)
    : HttpSessionLink("duet", std::move(settings), http, std::move(log)) {
    session_ = std::make_unique<DuetSession>(DuetSession{*this, settings_, std::nullopt, 0});
}

DuetLink::~DuetLink() {
    finish_requests();
    session_->disconnect();
}

void DuetLink::run_job(const std::vector<std::string>& lines, Done done) {
    std::string text = joined(lines);
    start_in_session(
        [this, text = std::move(text)](DuetSession& s) {
            s.ensure_ready();
            const std::string path = "0:/gcodes/" + settings_.job_file_name;
            s.upload(path, text);
            s.gcode("M32 \"" + path + "\"");
            return follow_print(settings_.poll_interval, settings_.reply_timeout, [&](bool) {
                PrintReport report;
                report.state = s.status();
                const std::string& status = report.state;
                if (status == "halted")
                    throw LinkError("the printer halted on the host (emergency stop)");
                report.printing = status == "processing" || status == "pausing" ||
                                  status == "paused" || status == "resuming" ||
                                  status == "cancelling" || status == "simulating";
                const json job = s.model("job");
                const bool ours = job.value("lastFileName", json()) == json(path);
                if (status == "idle" && ours) {
                    if (job.value("lastFileCancelled", false))
                        report.over =
                            JobOutcome{false, "the print was cancelled on the host", {}, {}};
                    else if (job.value("lastFileAborted", false))
                        report.over = JobOutcome{false, "the print failed on the host", {}, {}};
                    else
                        report.over = JobOutcome{true, {}, {}, {}};
                }
                return report;
            });
        },
        std::move(done));
}

}  // namespace calbox::firmware
