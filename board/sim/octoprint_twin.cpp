#include "board/sim/octoprint_twin.hpp"

#include <atomic>
#include <chrono>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "board/sim/sim_board.hpp"
#include "drivers/http_server.hpp"

namespace calbox::sim {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

hal::ServerResponse error_reply(int status, const std::string& message) {
    return {status, "application/json", json{{"error", message}}.dump()};
}

}  // namespace

struct OctoPrintTwin::State final : TwinHostCore {
    using TwinHostCore::TwinHostCore;
    std::mutex mutex;  // the printer's port: one command batch at a time
    int sessions = 0;
    Clock::time_point key_asked{};

    bool authorised(const hal::ServerRequest& r) const {
        const std::string wanted = faults.wrong_key ? key + "-rotated" : key;
        const auto it = r.headers.find("x-api-key");
        return it != r.headers.end() && it->second == wanted;
    }

    // Marlin's answers to each command, as OctoPrint's terminal shows them, pushed on the socket.
    void run_commands(const json& commands) {
        std::vector<std::string> logs;
        for (const auto& c : commands) {
            if (!c.is_string()) continue;
            const std::string line = c.get<std::string>();
            logs.push_back("Send: " + line);
            if (line.rfind("M118 ", 0) == 0) {
                logs.push_back("Recv: " + line.substr(5));  // Marlin echoes M118's text
            } else {
                try {
                    for (const auto& r : bench->run_printer_line(line))
                        logs.push_back("Recv: " + r);
                } catch (const std::exception& e) {
                    logs.push_back(std::string("Recv: Error:") + e.what());
                }
            }
            logs.emplace_back("Recv: ok");
        }
        server->push(
            json{{"current", {{"logs", logs}, {"state", {{"text", "Operational"}}}}}}.dump());
    }

    std::string state_text() const {
        switch (print->state()) {
            case TwinPrint::State::printing:
                return "Printing";
            case TwinPrint::State::error:
                return "Error: " + print->message();
            default:
                return "Operational";
        }
    }

    hal::ServerResponse http(const hal::ServerRequest& r) {
        const int n = count_request();
        if (held_silent(n)) return error_reply(503, "stopping");
        if (restarts_at(n)) return error_reply(503, "restarting");
        if (restarting()) return error_reply(503, "OctoPrint is starting");
        // The application keys plugin: no key needed to ask for one.
        if (r.method == "POST" && r.target == "/plugin/appkeys/request") {
            const std::lock_guard lock(mutex);
            key_asked = Clock::now();
            return {201, "application/json", json{{"app_token", "twin-token"}}.dump()};
        }
        if (r.method == "GET" && r.target == "/plugin/appkeys/request/twin-token") {
            const std::lock_guard lock(mutex);
            if (key_asked == Clock::time_point{}) return error_reply(404, "Not found");
            if (Clock::now() - key_asked < std::chrono::seconds(1))
                return {202, "application/json", "{}"};
            return {200, "application/json", json{{"api_key", key}}.dump()};
        }
        if (!authorised(r)) return error_reply(403, "Invalid API key");
        if (r.method == "POST" && r.target == "/api/login") {
            const std::lock_guard lock(mutex);
            return {200, "application/json",
                    json{{"name", "twin"}, {"session", "session-" + std::to_string(++sessions)}}
                        .dump()};
        }
        if (r.method == "POST" && r.target == "/api/printer/command") {
            if (faults.printer_not_ready) return error_reply(409, "Printer is not operational");
            const json body = json::parse(r.body, nullptr, false);
            if (body.is_discarded() || !body.contains("commands") || !body["commands"].is_array())
                return error_reply(400, "Expected commands");
            const std::lock_guard lock(mutex);
            if (print->state() == TwinPrint::State::printing)
                return error_reply(409, "Printer is currently printing");
            run_commands(body["commands"]);
            return {204, "application/json", ""};
        }
        if (r.method == "POST" && r.target == "/api/files/local") {
            const auto type =
                r.headers.count("content-type") != 0 ? r.headers.at("content-type") : std::string();
            const auto fields = form_fields(type, r.body);
            if (fields.count("file") == 0) return error_reply(400, "No file included");
            if (faults.upload_refused) return error_reply(409, "Insufficient disk space");
            const auto& [name, contents] = fields.at("file");
            if (name.empty() || name.find('/') != std::string::npos || name[0] == '.')
                return error_reply(415, "Invalid file name");
            std::filesystem::create_directories(dir / "uploads");
            write_file_whole(dir / "uploads" / name, contents);
            if (fields.count("print") != 0 && fields.at("print").second == "true") {
                if (faults.printer_not_ready)
                    return error_reply(409, "Can not print: printer is not operational");
                const std::lock_guard lock(mutex);
                if (faults.print_never_starts)
                    return {201, "application/json",
                            json{{"done", true}, {"files", {{"local", {{"name", name}}}}}}.dump()};
                try {
                    print->start(name, contents, print_seconds,
                                 faults.print_cancelled && print->started() == 0);
                } catch (const std::logic_error& e) {
                    return error_reply(409, e.what());
                }
            }
            return {201, "application/json",
                    json{{"done", true}, {"files", {{"local", {{"name", name}}}}}}.dump()};
        }
        if (r.method == "GET" && r.target == "/api/job") {
            const std::lock_guard lock(mutex);
            json job = {{"state", state_text()},
                        {"job", {{"file", {{"name", nullptr}}}}},
                        {"progress", {{"completion", nullptr}}}};
            if (print->started() > 0) {
                job["job"]["file"]["name"] = print->name();
                job["progress"]["completion"] = 100.0 * print->completion();
            }
            return {200, "application/json", job.dump()};
        }
        return error_reply(404, "Not found");
    }
};

OctoPrintTwin::OctoPrintTwin(std::shared_ptr<TwinBench> bench, std::filesystem::path host_dir,
                             TwinHostSettings settings)
    : state_(std::make_unique<State>(std::move(bench), std::move(host_dir), std::move(settings))) {
    auto& s = *state_;
    s.server = std::make_unique<drivers::HttpServer>(
        "127.0.0.1", 0,
        drivers::HttpServer::Handlers{
            [&s](const hal::ServerRequest& r) { return s.http(r); },
            // OctoPrint's socket takes anyone; what it pushes follows an auth message.
            [](const hal::ServerRequest& r) { return r.target == "/sockjs/websocket" ? 101 : 404; },
            [](const hal::ServerRequest&, const std::string&) {
                return std::vector<std::string>{};
            }});
}

OctoPrintTwin::~OctoPrintTwin() {
    state_->shut_down();
}

std::string OctoPrintTwin::url() const {
    return state_->url();
}

}  // namespace calbox::sim
