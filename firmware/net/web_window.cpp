#include "firmware/net/web_window.hpp"

#include <algorithm>
#include <cctype>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string_view>

#include "core/modes/compensate_job.hpp"
#include "core/number_text.hpp"
#include "firmware/console/job_desk.hpp"
#include "firmware/net/place_view.hpp"
#include "firmware/net/web_page.hpp"

namespace calbox::firmware {
namespace {

using hal::ServerRequest;
using hal::ServerResponse;
using json = nlohmann::json;

// The loop did not answer in time (stopped, or the inbox going).
struct Busy {};

ServerResponse json_answer(const json& j) {
    return {200, "application/json", j.dump() + "\n", {}};
}

std::string percent_decoded(const std::string& text) {
    std::string out;
    for (std::size_t i = 0; i < text.size(); ++i) {
        if (text[i] == '%' && i + 2 < text.size() &&
            std::isxdigit(static_cast<unsigned char>(text[i + 1])) &&
            std::isxdigit(static_cast<unsigned char>(text[i + 2]))) {
            out += static_cast<char>(std::stoi(text.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else {
            out += text[i];
        }
    }
    return out;
}

// One query parameter's value ("after=12&x=1"), or empty.
std::string query_value(const std::string& query, const std::string& name) {
    std::size_t at = 0;
    while (at <= query.size()) {
        const auto end = std::min(query.find('&', at), query.size());
        const std::string pair = query.substr(at, end - at);
        if (pair.rfind(name + "=", 0) == 0) return percent_decoded(pair.substr(name.size() + 1));
        at = end + 1;
    }
    return {};
}

// The records a page may read: each cycle's, the set-up's and the mode's kept files. Not the
// configuration (it holds the password's hash), nor anything else the data directory gathers.
bool is_record_name(const std::string& name, const std::vector<std::string>& kept_files) {
    static const char* const setup[] = {"camera.yaml",  "plane.yaml",   "reference.yaml",
                                        "history.json", "bed-view.png", "bed-view.pgw",
                                        kFoundStockFile};
    if (name.empty() || name.size() > 128 || name.front() == '.') return false;
    if (name.find_first_not_of(
            "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-") !=
        std::string::npos)
        return false;
    if (name.rfind("cycle-", 0) == 0 || name.rfind("job-", 0) == 0) return true;
    return std::find(std::begin(setup), std::end(setup), name) != std::end(setup) ||
           std::find(kept_files.begin(), kept_files.end(), name) != kept_files.end();
}

std::string content_type_of(const std::string& name) {
    const auto dot = name.rfind('.');
    const std::string ext = dot == std::string::npos ? "" : name.substr(dot + 1);
    if (ext == "png") return "image/png";
    if (ext == "jpg" || ext == "jpeg") return "image/jpeg";
    if (ext == "json") return "application/json";
    if (ext == "csv") return "text/csv; charset=utf-8";
    if (ext == "yaml" || ext == "gcode" || ext == "txt" || ext == "cfg")
        return "text/plain; charset=utf-8";
    return "application/octet-stream";
}

// What every answer carries: nothing cached, nothing sniffed, not framed by another site.
void secure(ServerResponse& r) {
    r.headers.emplace_back("X-Content-Type-Options", "nosniff");
    r.headers.emplace_back("X-Frame-Options", "DENY");
    r.headers.emplace_back("Referrer-Policy", "no-referrer");
    if (std::none_of(r.headers.begin(), r.headers.end(),
                     [](const auto& h) { return h.first == "Cache-Control"; }))
        r.headers.emplace_back("Cache-Control", "no-store");
}

// The page's actions that carry words of their own, each the console command it stands for:
// its line built from plain words only, or none when the body is not one (answered with its
// usage).
std::optional<std::string> compensate_line(const json& body) {
    // The console's `compensate`, one line built from plain words.
    const std::string job = body.value("job", std::string());
    const std::string zero = body.value("work_zero", std::string());
    const auto word_chars = [](const std::string& s) {
        return s.find_first_not_of(
                   "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                   "0123456789._-,= ") == std::string::npos;
    };
    if (job.empty() || job.size() > 100 || zero.size() > 120 || !word_chars(job) ||
        job.find(' ') != std::string::npos || !word_chars(zero) ||
        zero.find("--") != std::string::npos || body.size() > 3)
        return std::nullopt;
    return "compensate " + job + (zero.empty() ? "" : " " + zero);
}

std::optional<std::string> work_zero_line(const json& body) {
    // The console's `work zero`: what would be sent, or with confirm sent.
    const auto zero = body.find("work_zero");
    const auto confirm = body.find("confirm");
    if (body.size() > 3 || zero == body.end() || !zero->is_string() || zero->empty() ||
        zero->get<std::string>().size() > 60 ||
        zero->get<std::string>().find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789.,- ") !=
            std::string::npos ||
        zero->get<std::string>().find("--") != std::string::npos ||
        (confirm != body.end() && !confirm->is_boolean()))
        return std::nullopt;
    const bool confirmed = confirm != body.end() && confirm->get<bool>();
    return "work zero " + zero->get<std::string>() + (confirmed ? " confirm" : "");
}

std::optional<std::string> probe_stock_line(const json& body) {
    // The console's `probe stock`: what would be sent, or with confirm sent.
    const auto plain_point = [&body](const char* key) {
        const auto p = body.find(key);
        return p != body.end() && p->is_string() && !p->empty() &&
               p->get<std::string>().size() <= 40 &&
               p->get<std::string>().find_first_not_of("0123456789.,-") == std::string::npos;
    };
    const auto confirm = body.find("confirm");
    const bool points = body.contains("on") || body.contains("beside");
    if (body.size() > 4 || (points && (!plain_point("on") || !plain_point("beside"))) ||
        (confirm != body.end() && !confirm->is_boolean()))
        return std::nullopt;
    std::string line = "probe stock";
    if (points)
        line += " " + body["on"].get<std::string>() + " " + body["beside"].get<std::string>();
    if (confirm != body.end() && confirm->get<bool>()) line += " confirm";
    return line;
}

std::optional<std::string> bed_photo_line(const json& body) {
    // The console's `bed photo`, its figures checked there: the marks as plain numbers.
    const auto surface = body.find("surface_mm");
    const auto marks = body.find("marks");
    const auto diameter = body.find("mark_diameter_mm");
    const bool marks_plain =
        marks == body.end() ||
        (marks->is_string() && !marks->empty() && marks->get<std::string>().size() <= 120 &&
         marks->get<std::string>().find_first_not_of("0123456789.,- ") == std::string::npos);
    if (body.size() > 4 || (surface != body.end() && !surface->is_number()) || !marks_plain ||
        (diameter != body.end() && (!diameter->is_number() || marks == body.end())))
        return std::nullopt;
    std::string line = "bed photo";
    if (surface != body.end()) line += " " + number_text("%.3f", surface->get<double>());
    if (marks != body.end()) line += " marks " + marks->get<std::string>();
    if (diameter != body.end()) line += " diameter " + number_text("%.3f", diameter->get<double>());
    return line;
}

struct PageAction {
    std::string_view name;
    std::optional<std::string> (*console_line)(const json& body);
    std::string_view usage;
};

constexpr PageAction kPageActions[] = {
    {"compensate", compensate_line,
     "compensate: {\"action\": \"compensate\", \"job\": \"job-NAME.nc\", "
     "\"work_zero\": \"X,Y|measured|controller|G54=X,Y ...\"}"},
    {"work-zero", work_zero_line,
     "work-zero: {\"action\": \"work-zero\", \"work_zero\": "
     "\"X,Y|camera [CORNER]\", \"confirm\": true|false}"},
    {"probe-stock", probe_stock_line,
     "probe-stock: {\"action\": \"probe-stock\", \"on\": \"X,Y\", "
     "\"beside\": \"X,Y\", \"confirm\": true|false} (the points "
     "together or neither)"},
    {"bed-photo", bed_photo_line,
     "bed-photo: {\"action\": \"bed-photo\", \"surface_mm\": MM, "
     "\"marks\": \"X,Y X,Y X,Y [X,Y]\", \"mark_diameter_mm\": MM} "
     "(each optional; a diameter with marks)"},
};

}  // namespace

ServerResponse error_answer(int status, const std::string& message, hal::Headers headers) {
    return {status, "application/json", json{{"error", message}}.dump() + "\n", std::move(headers)};
}

hal::ServerLimits server_limits(const WebLimits& limits) {
    hal::ServerLimits server;
    server.max_body_bytes = limits.max_body_bytes;
    server.max_connections = limits.max_connections;
    server.idle_timeout = limits.idle_timeout;
    return server;
}

WebWindow::WebWindow(WebWindowContext context, const std::string& host, int port, WebLimits limits,
                     const std::optional<hal::ServerTls>& tls)
    : c_(std::move(context)), limits_(limits) {
    server_ = c_.network.listen(host, port,
                                hal::HttpHandlers{[this](const ServerRequest& r) {
                                                      ServerResponse answer = this->answer(r);
                                                      secure(answer);
                                                      return answer;
                                                  },
                                                  [this](const ServerRequest& r) {
                                                      if (!take_token(r.peer)) return 429;
                                                      return r.target == "/events" ? 101 : 404;
                                                  },
                                                  [](const ServerRequest&, const std::string&) {
                                                      return std::vector<std::string>{};
                                                  }},
                                server_limits(limits_), tls);
}

WebWindow::~WebWindow() = default;

int WebWindow::port() const {
    return server_->port();
}

void WebWindow::push(const std::string& event_json) {
    server_->push(event_json);
}

template <class T>
T WebWindow::on_loop(std::function<T()> job) {
    std::optional<T> result;
    try {
        result = c_.inbox.call<T>(std::move(job), limits_.loop_answer);
    } catch (const std::future_error&) {
        throw Busy{};
    }
    if (!result) throw Busy{};
    return std::move(*result);
}

bool WebWindow::take_token(const std::string& peer) {
    const auto now = c_.clock.now();
    const std::lock_guard lock(peers_mutex_);
    // A flood from many addresses must not grow the table without end: the quiet ones go.
    if (peers_.size() > 1024) {
        for (auto it = peers_.begin(); it != peers_.end();) {
            if (now - it->second.refilled > std::chrono::seconds(60) &&
                it->second.locked_until < now)
                it = peers_.erase(it);
            else
                ++it;
        }
    }
    auto [it, fresh] = peers_.try_emplace(peer);
    Peer& p = it->second;
    if (fresh) {
        p.tokens = limits_.burst;
        p.refilled = now;
    }
    const double seconds = std::chrono::duration<double>(now - p.refilled).count();
    p.tokens = std::min(limits_.burst, p.tokens + seconds * limits_.requests_per_second);
    p.refilled = now;
    if (p.tokens < 1) return false;
    p.tokens -= 1;
    return true;
}

std::optional<ServerResponse> WebWindow::refuse_password(const ServerRequest& request) {
    const std::string hash = on_loop<std::string>(c_.password_hash);
    if (hash.empty())
        return error_answer(
            403,
            "no web password is set on the box: the page changes nothing until one is "
            "(the console's `web password`)");
    const auto now = c_.clock.now();
    {
        const std::lock_guard lock(peers_mutex_);
        const Peer& p = peers_[request.peer];
        if (p.locked_until > now)
            return error_answer(
                429, "too many wrong passwords: wait and try again",
                {{"Retry-After", std::to_string(limits_.wrong_password_wait.count())}});
    }
    const auto header = request.headers.find("authorization");
    const auto password =
        header == request.headers.end() ? std::nullopt : net::basic_auth_password(header->second);
    if (!password)
        return error_answer(401, "this needs the box's web password (HTTP Basic authorization)");
    const bool right = c_.network.passwords().matches(*password, hash);
    const std::lock_guard lock(peers_mutex_);
    Peer& p = peers_[request.peer];
    if (right) {
        p.wrong_passwords = 0;
        return std::nullopt;
    }
    if (++p.wrong_passwords >= limits_.wrong_passwords) {
        p.wrong_passwords = 0;
        p.locked_until = now + limits_.wrong_password_wait;
    }
    return error_answer(401, "wrong web password");
}

ServerResponse WebWindow::console_answer(const std::string& line) {
    const std::string reply = on_loop<std::string>([this, line] { return c_.console(line); });
    json j = json::parse(reply);
    if (!j.value("ok", false)) return error_answer(409, j.value("error", std::string("refused")));
    return json_answer(j);
}

ServerResponse WebWindow::answer(const ServerRequest& request) {
    if (!take_token(request.peer))
        return error_answer(429,
                            "too many requests: at most " +
                                std::to_string(static_cast<int>(limits_.requests_per_second)) +
                                " a second",
                            {{"Retry-After", "1"}});
    const auto q = request.target.find('?');
    const std::string path = request.target.substr(0, q);
    const std::string query = q == std::string::npos ? "" : request.target.substr(q + 1);
    try {
        return route(request, path, query);
    } catch (const Busy&) {
        return error_answer(503, "the box did not answer in time: try again",
                            {{"Retry-After", "2"}});
    }
}

ServerResponse WebWindow::route(const ServerRequest& request, const std::string& path,
                                const std::string& query) {
    if (request.method == "POST") return post(request, path);
    if (request.method != "GET")
        return error_answer(405, request.method + " is not served here", {{"Allow", "GET, POST"}});
    if (path == "/" || path == "/index.html") {
        ServerResponse r{200, "text/html; charset=utf-8", std::string(web_page_html()), {}};
        r.headers.emplace_back("Content-Security-Policy",
                               "default-src 'self'; img-src 'self' data: blob:; style-src 'self'; "
                               "script-src 'self'; connect-src 'self'; frame-ancestors 'none'");
        return r;
    }
    if (path == "/app.js")
        return {200, "text/javascript; charset=utf-8", std::string(web_page_script()), {}};
    if (path == "/style.css")
        return {200, "text/css; charset=utf-8", std::string(web_page_style()), {}};
    if (path == "/api/status") return json_answer(on_loop<json>(c_.status));
    if (path == "/api/history") return json_answer(on_loop<json>(c_.history));
    if (path == "/api/config") {
        const ServerResponse r = console_answer("config list --json");
        json j = json::parse(r.body);
        // Its hash is the box's alone: the page shows only whether one is set.
        auto& config = j["config"];
        const bool set = !config["web.password"]["value"].get<std::string>().empty();
        config.erase("web.password");
        return json_answer({{"config", config}, {"web_password_set", set}});
    }
    if (path == "/metrics") {
        return {
            200, "text/plain; version=0.0.4; charset=utf-8", on_loop<std::string>(c_.metrics), {}};
    }
    if (path == "/live.jpg") return live(query);
    if (path == "/api/place") return place(query);
    if (path == "/records" || path == "/records/") {
        json list = json::array();
        for (const auto& e : c_.records.list_files())
            if (is_record_name(e.name, c_.kept_files))
                list.push_back({{"name", e.name}, {"bytes", e.size_bytes}});
        std::sort(list.begin(), list.end(),
                  [](const json& a, const json& b) { return a["name"] < b["name"]; });
        return json_answer({{"records", list}});
    }
    if (path.rfind("/records/", 0) == 0) return record(percent_decoded(path.substr(9)), query);
    return error_answer(404, "nothing at " + path);
}

ServerResponse WebWindow::record(const std::string& name, const std::string& query) {
    if (!is_record_name(name, c_.kept_files))
        return error_answer(403,
                            "not a record: /records/ serves the cycles' records and the set-up's "
                            "files by their plain names");
    const auto contents = c_.records.read_file(name);
    if (!contents) return error_answer(404, "no record " + name);
    ServerResponse r{200, content_type_of(name), *contents, {}};
    if (query_value(query, "download") == "1")
        r.headers.emplace_back("Content-Disposition", "attachment; filename=\"" + name + "\"");
    return r;
}

ServerResponse WebWindow::place(const std::string& query) {
    const std::string job = query_value(query, "job");
    const std::string zero = query_value(query, "work_zero");
    if (compensated_job_name(job).empty())
        return error_answer(400, "place: job=job-NAME.EXT, a job in the data directory");
    if (zero.size() > 120) return error_answer(400, "place: work_zero=X,Y (or G54=X,Y ...)");
    const auto kept = on_loop<std::optional<std::string>>(c_.kept_result);
    if (!kept)
        return error_answer(409,
                            "place: no correction in force: the box keeps none for this "
                            "machine yet (calibrate it first)");
    const auto text = c_.records.read_file(job);
    if (!text) return error_answer(404, "place: no " + job + " in the data directory");
    // Worked out on the server's thread: a long job does not hold up the loop.
    try {
        return json_answer(job_outline_json(
            *kept, *text, job, zero,
            found_file_for(zero) ? c_.records.read_file(*found_file_for(zero)) : std::nullopt));
    } catch (const modes::JobError& e) {
        return error_answer(409, e.what());
    }
}

ServerResponse WebWindow::live(const std::string& query) {
    std::uint64_t after = 0;
    const std::string after_text = query_value(query, "after");
    if (!after_text.empty()) {
        if (after_text.size() > 19 ||
            after_text.find_first_not_of("0123456789") != std::string::npos)
            return error_answer(400, "after: a frame number");
        after = std::stoull(after_text);
    }
    // A fresh frame when the camera is free; while the cycle uses it, its own photos show.
    (void)on_loop<bool>(c_.preview);
    c_.frames.wait_past(after, std::chrono::seconds(10));
    const LiveGuide guide = on_loop<LiveGuide>(c_.guide);
    const auto image = live_view_.of_newest(c_.frames, guide, limits_.live_width_px);
    if (!image) return error_answer(503, "no frame from the camera yet", {{"Retry-After", "1"}});
    ServerResponse r{200, "image/jpeg", image->jpeg, {}};
    r.headers.emplace_back("X-Frame", std::to_string(image->sequence));
    r.headers.emplace_back("X-Sharpness", std::to_string(static_cast<long>(image->sharpness)));
    return r;
}

ServerResponse WebWindow::post(const ServerRequest& request, const std::string& path) {
    if (path != "/api/action" && path != "/api/config")
        return error_answer(404, "nothing at " + path);
    const auto type = request.headers.find("content-type");
    if (type == request.headers.end() || type->second.rfind("application/json", 0) != 0)
        return error_answer(415, "the body must be JSON (Content-Type: application/json)");
    if (auto refused = refuse_password(request)) return *refused;
    json body;
    try {
        body = json::parse(request.body);
    } catch (const json::parse_error& e) {
        return error_answer(400, std::string("malformed JSON: ") + e.what());
    }
    if (!body.is_object()) return error_answer(400, "the body must be a JSON object");
    return path == "/api/action" ? post_action(body) : post_config(body);
}

ServerResponse WebWindow::post_action(const json& body) {
    const auto given = body.find("action");
    const std::string name =
        given != body.end() && given->is_string() ? given->get<std::string>() : std::string();
    for (const auto& action : kPageActions) {
        if (name != action.name) continue;
        const auto line = action.console_line(body);
        if (!line) return error_answer(400, std::string(action.usage));
        return console_answer(*line + " --json");
    }
    static const char* const actions[] = {"start", "confirm", "cancel", "acknowledge", "revert"};
    if (std::find(std::begin(actions), std::end(actions), name) == std::end(actions))
        return error_answer(400, "action: one of start, confirm, cancel, acknowledge, revert");
    return console_answer(name + " --json");
}

ServerResponse WebWindow::post_config(const json& body) {
    if (body.contains("save")) {
        if (body.size() != 1 || body["save"] != true) return error_answer(400, "save: true, alone");
        return console_answer("config save --json");
    }
    const auto key = body.find("key");
    const auto value = body.find("value");
    if (key == body.end() || !key->is_string() || value == body.end() || !value->is_string() ||
        body.size() != 2)
        return error_answer(
            400, "a configuration change is {\"key\": \"table.key\", \"value\": \"text\"}");
    const std::string k = key->get<std::string>(), v = value->get<std::string>();
    const auto plain = [](const std::string& s) {
        return std::none_of(s.begin(), s.end(), [](char ch) {
            return static_cast<unsigned char>(ch) < 0x20 || ch == 0x7f;
        });
    };
    if (k.empty() || k.size() > 64 || v.size() > 200 || !plain(k) || !plain(v) ||
        k.find_first_of(" \t") != std::string::npos || v.find("--json") != std::string::npos)
        return error_answer(400, "a key is one word, a value one line without control characters");
    if (k == "web.password")
        return error_answer(403, "the web password is set on the console only");
    return console_answer("config set " + k + " " + (v.empty() ? "\"\"" : v) + " --json");
}

}  // namespace calbox::firmware
