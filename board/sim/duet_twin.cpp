#include "board/sim/duet_twin.hpp"

#include <atomic>
#include <boost/crc.hpp>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "board/sim/sim_board.hpp"
#include "drivers/http_server.hpp"

namespace calbox::sim {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// A query string's parameters, percent-decoded.
std::map<std::string, std::string> query_of(const std::string& target) {
    std::map<std::string, std::string> out;
    const auto q = target.find('?');
    if (q == std::string::npos) return out;
    std::string rest = target.substr(q + 1);
    std::size_t at = 0;
    while (at <= rest.size()) {
        const auto amp = rest.find('&', at);
        const std::string pair = rest.substr(at, amp == std::string::npos ? amp : amp - at);
        const auto eq = pair.find('=');
        std::string value;
        const std::string raw = eq == std::string::npos ? "" : pair.substr(eq + 1);
        for (std::size_t i = 0; i < raw.size(); ++i) {
            if (raw[i] == '%' && i + 2 < raw.size() &&
                std::isxdigit(static_cast<unsigned char>(raw[i + 1])) != 0 &&
                std::isxdigit(static_cast<unsigned char>(raw[i + 2])) != 0) {
                value += static_cast<char>(std::stoi(raw.substr(i + 1, 2), nullptr, 16));
                i += 2;
            } else {
                value += raw[i] == '+' ? ' ' : raw[i];
            }
        }
        out[pair.substr(0, eq)] = value;
        if (amp == std::string::npos) break;
        at = amp + 1;
    }
    return out;
}

std::string path_of(const std::string& target) {
    return target.substr(0, target.find('?'));
}

hal::ServerResponse json_reply(const json& j) {
    return {200, "application/json", j.dump()};
}

}  // namespace

struct DuetTwin::State final : TwinHostCore {
    using TwinHostCore::TwinHostCore;
    std::mutex mutex;
    std::string session_key;
    std::string reply;  // what rr_reply hands out next
    int disconnects = 0;
    bool restarted_at_command = false;

    // Under the mutex: host_restart_at_command's line arrived (the first time): the board
    // restarts before running it.
    bool restarts_on(const std::string& line) {
        if (faults.restart_at_command.empty() || restarted_at_command ||
            line.rfind(faults.restart_at_command, 0) != 0)
            return false;
        restarted_at_command = true;
        session_key.clear();
        restart_now();
        return true;
    }

    std::string status() const {
        if (faults.printer_not_ready) return "off";
        return print->state() == TwinPrint::State::printing ? "processing" : "idle";
    }

    // One line of G-code from rr_gcode, under the mutex: its reply kept for rr_reply.
    void run(const std::string& line) {
        if (line.rfind("M118 ", 0) == 0) {
            const auto q = line.find('"');
            reply += line.substr(q + 1, line.rfind('"') - q - 1) + "\n";
            return;
        }
        if (line.rfind("M32 ", 0) == 0) {
            const auto q = line.find('"');
            const std::string path = line.substr(q + 1, line.rfind('"') - q - 1);
            const std::string name = path.substr(path.rfind('/') + 1);
            if (faults.print_never_starts) return;
            try {
                print->start(path, read_whole_file(dir / "gcodes" / name), print_seconds,
                             faults.print_cancelled && print->started() == 0);
            } catch (const std::exception& e) {
                reply += "Error: M32: " + std::string(e.what()) + "\n";
            }
            return;
        }
        if (print->state() == TwinPrint::State::printing) {
            reply += "Error: busy printing\n";
            return;
        }
        try {
            for (const auto& r : bench->run_printer_line(line)) reply += r + "\n";
        } catch (const std::exception& e) {
            reply += "Error: " + std::string(e.what()) + "\n";
        }
    }

    hal::ServerResponse http(const hal::ServerRequest& r) {
        const int n = count_request();
        if (held_silent(n)) return {503, "text/plain", "stopping"};
        if (restarts_at(n)) {
            const std::lock_guard lock(mutex);
            session_key.clear();
            return {503, "text/plain", "restarting"};
        }
        const std::lock_guard lock(mutex);
        if (restarting()) return {503, "text/plain", "starting"};
        const std::string path = path_of(r.target);
        const auto query = query_of(r.target);
        if (duet_sbc) return sbc_http(r, path, query, n);
        if (path == "/rr_connect") {
            // The board's password is the host's key.
            const std::string wanted = faults.wrong_key ? key + "-changed" : key;
            if (query.count("password") == 0 || query.at("password") != wanted)
                return json_reply({{"err", 1}});
            session_key = std::to_string(1000 + n);
            return json_reply({{"err", 0},
                               {"sessionTimeout", 8000},
                               {"boardType", "duet3mb6hc102"},
                               {"apiLevel", 1},
                               {"sessionKey", std::stol(session_key)}});
        }
        const auto key = r.headers.find("x-session-key");
        if (session_key.empty() || key == r.headers.end() || key->second != session_key)
            return {401, "text/plain", ""};
        if (path == "/rr_disconnect") {
            session_key.clear();
            ++disconnects;
            return json_reply({{"err", 0}});
        }
        if (path == "/rr_gcode") {
            const std::string line = query.count("gcode") != 0 ? query.at("gcode") : "";
            if (restarts_on(line)) return {503, "text/plain", "restarting"};
            if (status() != "off") run(line);
            return json_reply({{"buff", 255}});
        }
        if (path == "/rr_reply") {
            std::string out;
            out.swap(reply);
            return {200, "text/plain", out};
        }
        if (path == "/rr_upload" && r.method == "POST") {
            if (faults.upload_refused) return json_reply({{"err", 1}});
            boost::crc_32_type crc;
            crc.process_bytes(r.body.data(), r.body.size());
            char hex[16];
            std::snprintf(hex, sizeof hex, "%08x", crc.checksum());
            if (query.count("crc32") == 0 || query.at("crc32") != hex)
                return json_reply({{"err", 1}});
            const std::string name = query.count("name") != 0 ? query.at("name") : "";
            const std::string file = name.substr(name.rfind('/') + 1);
            if (name.rfind("0:/gcodes/", 0) != 0 || file.empty() || file[0] == '.')
                return json_reply({{"err", 1}});
            std::filesystem::create_directories(dir / "gcodes");
            write_file_whole(dir / "gcodes" / file, r.body);
            return json_reply({{"err", 0}});
        }
        if (path == "/rr_model") {
            const std::string k = query.count("key") != 0 ? query.at("key") : "";
            const json model = object_model();
            const json result = model.contains(k) ? model[k] : json::object();
            return json_reply({{"key", k}, {"flags", "d99f"}, {"result", result}});
        }
        return {404, "text/plain", "not found"};
    }

    json object_model() const {
        const auto s = print->state();
        return {{"state", {{"status", status()}}},
                {"job",
                 {{"lastFileName", print->started() > 0 ? json(print->name()) : json()},
                  {"lastFileCancelled", s == TwinPrint::State::cancelled},
                  {"lastFileAborted", s == TwinPrint::State::error}}}};
    }

    // DuetSoftwareFramework's HTTP API on the SBC (DuetWebServer), under the mutex: no rr_.
    hal::ServerResponse sbc_http(const hal::ServerRequest& r, const std::string& path,
                                 const std::map<std::string, std::string>& query, int n) {
        if (path.rfind("/machine/", 0) != 0) return {404, "text/plain", "not found"};
        if (path == "/machine/connect") {
            const std::string wanted = faults.wrong_key ? key + "-changed" : key;
            if (query.count("password") == 0 || query.at("password") != wanted)
                return {403, "text/plain", "Invalid password"};
            session_key = "dsf-" + std::to_string(1000 + n);
            return json_reply({{"sessionKey", session_key}, {"sessionTimeout", 8000}});
        }
        const auto given = r.headers.find("x-session-key");
        if (session_key.empty() || given == r.headers.end() || given->second != session_key)
            return {401, "text/plain", ""};
        if (path == "/machine/disconnect") {
            session_key.clear();
            ++disconnects;
            return {204, "text/plain", ""};
        }
        if (path == "/machine/code" && r.method == "POST") {
            reply.clear();
            std::istringstream codes(r.body);
            for (std::string line; std::getline(codes, line);) {
                if (restarts_on(line)) return {503, "text/plain", "restarting"};
                if (status() != "off") run(line);
            }
            std::string out;
            out.swap(reply);
            return {200, "text/plain", out};
        }
        if (path == "/machine/model") return json_reply(object_model());
        const std::string file_api = "/machine/file/";
        if (path.rfind(file_api, 0) == 0 && r.method == "PUT") {
            if (faults.upload_refused)
                return {500, "text/plain", "Not enough space on the SD card"};
            const auto decoded = query_of("?p=" + path.substr(file_api.size()));
            const std::string name = decoded.count("p") != 0 ? decoded.at("p") : "";
            const std::string file = name.substr(name.rfind('/') + 1);
            if (name.rfind("0:/gcodes/", 0) != 0 || file.empty() || file[0] == '.')
                return {400, "text/plain", "Invalid file name"};
            std::filesystem::create_directories(dir / "gcodes");
            write_file_whole(dir / "gcodes" / file, r.body);
            return {201, "text/plain", ""};
        }
        return {404, "text/plain", "not found"};
    }
};

DuetTwin::DuetTwin(std::shared_ptr<TwinBench> bench, std::filesystem::path host_dir,
                   TwinHostSettings settings)
    : state_(std::make_unique<State>(std::move(bench), std::move(host_dir), std::move(settings))) {
    auto& s = *state_;
    s.server = std::make_unique<drivers::HttpServer>(
        "127.0.0.1", 0,
        drivers::HttpServer::Handlers{[&s](const hal::ServerRequest& r) { return s.http(r); },
                                      [](const hal::ServerRequest&) { return 404; },
                                      [](const hal::ServerRequest&, const std::string&) {
                                          return std::vector<std::string>{};
                                      }});
}

int DuetTwin::sessions_closed() const {
    const std::lock_guard lock(state_->mutex);
    return state_->disconnects;
}

DuetTwin::~DuetTwin() {
    state_->shut_down();
}

std::string DuetTwin::url() const {
    return state_->url();
}

}  // namespace calbox::sim
