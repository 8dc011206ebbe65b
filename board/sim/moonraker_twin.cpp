#include "board/sim/moonraker_twin.hpp"

#include <array>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "board/sim/gcode_runner.hpp"
#include "board/sim/sim_board.hpp"
#include "drivers/http_server.hpp"

namespace calbox::sim {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using Sections = std::map<std::string, std::map<std::string, std::string>>;

std::string lower(std::string s) {
    for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

std::string trim(const std::string& s) {
    const auto first = s.find_first_not_of(" \t\r");
    if (first == std::string::npos) return {};
    return s.substr(first, s.find_last_not_of(" \t\r") - first + 1);
}

// printer.cfg as Klipper's configfile reads it: the body's sections, the SAVE_CONFIG block's
// over them (includes are not followed: the twin's printer.cfg has none).
Sections read_sections(const std::string& text) {
    Sections body, saved;
    std::string section;
    std::istringstream in(text);
    std::string raw;
    while (std::getline(in, raw)) {
        Sections* into = &body;
        std::string line = raw;
        if (line.rfind("#*#", 0) == 0) {
            into = &saved;
            line = line.substr(3);
        } else {
            // A comment starts a line, or follows whitespace.
            for (std::size_t i = 0; i < line.size(); ++i)
                if ((line[i] == '#' || line[i] == ';') &&
                    (i == 0 || std::isspace(static_cast<unsigned char>(line[i - 1])))) {
                    line.resize(i);
                    break;
                }
        }
        line = trim(line);
        if (line.empty() || line.rfind("<-", 0) == 0 || line.rfind("DO NOT EDIT", 0) == 0) continue;
        if (line.front() == '[' && line.back() == ']') {
            section = lower(trim(line.substr(1, line.size() - 2)));
            (*into)[section];
            continue;
        }
        const auto sep = line.find_first_of(":=");
        if (sep == std::string::npos || section.empty())
            throw std::runtime_error("File contains parsing errors: '" + line + "'");
        (*into)[section][lower(trim(line.substr(0, sep)))] = trim(line.substr(sep + 1));
    }
    for (const auto& [name, values] : saved)
        for (const auto& [key, value] : values) body[name][key] = value;
    return body;
}

double option(const Sections& s, const std::string& section, const std::string& key,
              const double* fallback = nullptr) {
    const auto sec = s.find(section);
    if (sec != s.end()) {
        const auto it = sec->second.find(key);
        if (it != sec->second.end()) {
            char* end = nullptr;
            const double v = std::strtod(it->second.c_str(), &end);
            if (end == it->second.c_str() || *end != '\0')
                throw std::runtime_error("Unable to parse option '" + key + "' in section '" +
                                         section + "'");
            return v;
        }
    }
    if (fallback != nullptr) return *fallback;
    throw std::runtime_error("Option '" + key + "' in section '" + section + "' must be specified");
}

constexpr std::array<double, 3> kDefaultAngleDeg = {210, 330, 90};
constexpr std::array<const char*, 3> kSteppers = {"stepper_a", "stepper_b", "stepper_c"};

// Every option the twin's printer takes, its defaults filled in, as configfile.settings gives
// them (numbers as numbers).
json settings_of(const Sections& s) {
    json out = json::object();
    for (const auto& [name, values] : s) {
        json section = json::object();
        for (const auto& [key, value] : values) {
            char* end = nullptr;
            const double v = std::strtod(value.c_str(), &end);
            if (!value.empty() && end != value.c_str() && *end == '\0')
                section[key] = v;
            else
                section[key] = value;
        }
        out[name] = section;
    }
    if (s.count("printer") == 0 || s.at("printer").count("kinematics") == 0 ||
        s.at("printer").at("kinematics") != "delta")
        return out;
    const double arm_a = option(s, "stepper_a", "arm_length");
    const double endstop_a = option(s, "stepper_a", "position_endstop");
    for (std::size_t i = 0; i < 3; ++i) {
        out[kSteppers[i]]["arm_length"] = option(s, kSteppers[i], "arm_length", &arm_a);
        out[kSteppers[i]]["position_endstop"] =
            option(s, kSteppers[i], "position_endstop", &endstop_a);
        out[kSteppers[i]]["angle"] = option(s, kSteppers[i], "angle", &kDefaultAngleDeg[i]);
    }
    return out;
}

json rpc_error(const json& id, int code, const std::string& message) {
    return {{"jsonrpc", "2.0"}, {"error", {{"code", code}, {"message", message}}}, {"id", id}};
}

hal::ServerResponse http_error(int status, const std::string& message) {
    return {status, "application/json",
            json{{"error", {{"code", status}, {"message", message}}}}.dump()};
}

std::string first_word(const std::string& line) {
    const auto t = trim(line);
    return t.substr(0, t.find_first_of(" \t"));
}

// A klippy command's NAME=value parameters.
std::map<std::string, std::string> parameters(const std::string& line) {
    std::map<std::string, std::string> out;
    std::istringstream in(line);
    std::string word;
    in >> word;
    while (in >> word) {
        const auto eq = word.find('=');
        if (eq != std::string::npos) out[lower(word.substr(0, eq))] = word.substr(eq + 1);
    }
    return out;
}

std::string repr(double v) {
    char b[40];
    std::snprintf(b, sizeof b, "%.17g", v);
    return b;
}

// Klipper's SAVE_CONFIG: the block at the file's end rewritten with the pending values over its
// old ones, and the lines above it that the block now sets commented out.
std::string saved_config(const std::string& text, const Sections& pending) {
    const auto mark = text.find("#*# <");
    std::string body = mark == std::string::npos ? text : text.substr(0, mark);
    Sections block;
    if (mark != std::string::npos) {
        std::istringstream in(text.substr(mark));
        std::string raw, section;
        while (std::getline(in, raw)) {
            const std::string line = trim(raw.substr(std::min<std::size_t>(3, raw.size())));
            if (line.empty() || line.front() == '<' || line.rfind("DO NOT", 0) == 0) continue;
            if (line.front() == '[') {
                section = trim(line.substr(1, line.size() - 2));
                continue;
            }
            const auto eq = line.find('=');
            if (eq != std::string::npos)
                block[section][trim(line.substr(0, eq))] = trim(line.substr(eq + 1));
        }
    }
    for (const auto& [name, values] : pending)
        for (const auto& [key, value] : values) block[name][key] = value;
    std::istringstream in(body);
    std::string raw, section, out;
    while (std::getline(in, raw)) {
        const std::string line = trim(raw.substr(0, raw.find('#')));
        if (!line.empty() && line.front() == '[') {
            section = lower(trim(line.substr(1, line.size() - 2)));
        } else if (const auto sep = line.find_first_of(":=");
                   sep != std::string::npos && block.count(section) != 0 &&
                   block.at(section).count(lower(trim(line.substr(0, sep)))) != 0) {
            raw.insert(0, "#");
        }
        out += raw + "\n";
    }
    while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
    out +=
        "\n\n#*# <---------------------- SAVE_CONFIG ---------------------->\n"
        "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n";
    for (const auto& [name, values] : block) {
        out.append("#*#\n#*# [").append(name).append("]\n");
        for (const auto& [key, value] : values)
            out.append("#*# ").append(key).append(" = ").append(value).append("\n");
    }
    return out;
}

}  // namespace

CartesianFirmware twin_cartesian_from_printer_cfg(const std::string& text) {
    const Sections s = read_sections(text);
    const auto printer = s.find("printer");
    if (printer == s.end() || printer->second.count("kinematics") == 0 ||
        printer->second.at("kinematics") != "cartesian")
        throw std::runtime_error("the twin's Klipper printer is cartesian ([printer] kinematics)");
    CartesianFirmware f;
    const double x = option(s, "stepper_x", "rotation_distance");
    const double y = option(s, "stepper_y", "rotation_distance");
    if (!(x > 0) || !(y > 0))
        throw std::runtime_error(
            "Option 'rotation_distance' in section 'stepper_x' must be above 0");
    f.travel_x = kOwnersRotationDistanceMm / x;
    f.travel_y = kOwnersRotationDistanceMm / y;
    return f;
}

std::string printer_cfg_of_cartesian(double bed_size_x_mm, double bed_size_y_mm) {
    char b[600];
    std::snprintf(b, sizeof b,
                  "# The twin Klipper cartesian printer's printer.cfg, as its owner wrote it.\n"
                  "[mcu]\nserial: /dev/serial/by-id/usb-Klipper_twin\n\n"
                  "[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 3000\n\n"
                  "[stepper_x]\nstep_pin: PF0\ndir_pin: PF1\nmicrosteps: 16\n"
                  "rotation_distance: %.0f\nendstop_pin: ^PE5\nposition_endstop: 0\n"
                  "position_max: %.0f\n\n"
                  "[stepper_y]\nstep_pin: PF6\ndir_pin: PF7\nmicrosteps: 16\n"
                  "rotation_distance: %.0f\nendstop_pin: ^PJ1\nposition_endstop: 0\n"
                  "position_max: %.0f\n\n"
                  "[skew_correction]\n",
                  kOwnersRotationDistanceMm, bed_size_x_mm, kOwnersRotationDistanceMm,
                  bed_size_y_mm);
    return b;
}

double twin_skew_factor(double ac_mm, double bd_mm, double ad_mm) {
    const double side = std::sqrt(2 * ac_mm * ac_mm + 2 * bd_mm * bd_mm - 4 * ad_mm * ad_mm) / 2;
    return std::tan(M_PI / 2 -
                    std::acos((ac_mm * ac_mm - side * side - ad_mm * ad_mm) / (2 * side * ad_mm)));
}

double twin_probe_z_offset(const std::string& text) {
    constexpr double kNone = 0;
    return option(read_sections(text), "probe", "z_offset", &kNone);
}

DeltaParams twin_params_from_printer_cfg(const std::string& text) {
    const Sections s = read_sections(text);
    const auto printer = s.find("printer");
    if (printer == s.end() || printer->second.count("kinematics") == 0 ||
        printer->second.at("kinematics") != "delta")
        throw std::runtime_error("the twin's Klipper printer is a delta ([printer] kinematics)");
    DeltaParams p;
    p.radius_mm = option(s, "printer", "delta_radius");
    const json settings = settings_of(s);
    std::array<double, 3> endstop{};
    for (std::size_t i = 0; i < 3; ++i) endstop[i] = settings[kSteppers[i]]["position_endstop"];
    // Marlin's conventions: the nozzle over the centre with every carriage at its trigger is
    // the lowest position_endstop; each other tower's carriage homes below its trigger by the
    // difference.
    p.height_mm = std::min({endstop[0], endstop[1], endstop[2]});
    p.diagonal_rod_mm = settings["stepper_a"]["arm_length"];
    for (std::size_t i = 0; i < 3; ++i) {
        p.diagonal_rod_trim_mm[i] =
            settings[kSteppers[i]]["arm_length"].get<double>() - p.diagonal_rod_mm;
        p.tower_angle_trim_deg[i] =
            settings[kSteppers[i]]["angle"].get<double>() - kDefaultAngleDeg[i];
        p.endstop_offset_mm[i] = p.height_mm - endstop[i];
    }
    if (!(p.diagonal_rod_mm > p.radius_mm))
        throw std::runtime_error("arm_length must exceed delta_radius");
    return p;
}

std::string printer_cfg_of(const DeltaParams& p, double print_radius_mm) {
    char b[200];
    std::string out =
        "# The twin Klipper delta's printer.cfg, as its owner wrote it.\n"
        "[mcu]\nserial: /dev/serial/by-id/usb-Klipper_twin\n\n"
        "[printer]\nkinematics: delta\nmax_velocity: 300\nmax_accel: 3000\n";
    std::snprintf(b, sizeof b, "delta_radius: %.4f\nprint_radius: %.1f\n\n", p.radius_mm,
                  print_radius_mm);
    out += b;
    for (std::size_t i = 0; i < 3; ++i) {
        std::snprintf(
            b, sizeof b,
            "[%s]\nstep_pin: PF%zu\ndir_pin: PF%zu\nmicrosteps: 16\n"
            "rotation_distance: 40\nendstop_pin: ^PE%zu\nhoming_speed: 50\n"
            "arm_length: %.4f\nangle: %.4f\nposition_endstop: %.4f\n\n",
            kSteppers[i], 2 * i, 2 * i + 1, i, p.diagonal_rod_mm + p.diagonal_rod_trim_mm[i],
            kDefaultAngleDeg[i] + p.tower_angle_trim_deg[i], p.height_mm - p.endstop_offset_mm[i]);
        out += b;
    }
    // A probe whose trigger sits 1.35 mm above the nozzle's tip.
    out += "[probe]\npin: ^PA1\nz_offset: 1.350\n";
    return out;
}

struct MoonrakerTwin::State final : TwinHostCore {
    using TwinHostCore::TwinHostCore;
    std::string first_config;  // as the twin started: new_config_rejected refuses another
    std::mutex mutex;
    std::string klippy_state = "ready", state_message = "Printer is ready";
    Clock::time_point ready_at{};  // a restart in progress ends then
    json settings = json::object();
    bool config_read_once = false;
    bool cartesian = false;  // else a delta
    // One-shot tokens handed out and not yet used, each with its expiry; those redeemed.
    std::map<std::string, Clock::time_point> tokens;
    int tokens_redeemed = 0;
    Sections pending;  // SAVE_CONFIG's to write (SKEW_PROFILE SAVE)
    bool restarted_at_command = false;

    // host_restart_at_command: the first G-code script with a line starting so restarts the host
    // (and Klipper with it) before any of it runs. A step of its own, whatever the requests
    // before it numbered.
    bool restarts_on(const std::string& method, const json& params) {
        if (faults.restart_at_command.empty() || restarted_at_command ||
            method != "printer.gcode.script")
            return false;
        std::istringstream script(params.value("script", std::string()));
        std::string line;
        bool found = false;
        while (!found && std::getline(script, line))
            found = line.rfind(faults.restart_at_command, 0) == 0;
        if (!found) return false;
        restarted_at_command = true;
        restart_now();
        return true;
    }

    // Klipper reads printer.cfg: ready, or its error.
    void load_config() {
        try {
            const std::string text = read_whole_file(dir / "printer.cfg");
            if (faults.new_config_rejected && text != first_config)
                throw std::runtime_error(
                    "Option 'position_endstop' in section 'stepper_a' must be below 400");
            if (cartesian)
                bench->restart_cartesian_printer(twin_cartesian_from_printer_cfg(text));
            else
                bench->restart_delta_printer(twin_params_from_printer_cfg(text),
                                             twin_probe_z_offset(text));
            settings = settings_of(read_sections(text));
            pending.clear();
            klippy_state = "ready";
            state_message = "Printer is ready";
        } catch (const std::exception& e) {
            klippy_state = "error";
            state_message = e.what();
        }
    }

    // Under the mutex: a restart that has run its time is over.
    void settle() {
        if (klippy_state == "startup" && !faults.printer_not_ready && Clock::now() >= ready_at)
            load_config();
    }

    void restart(std::chrono::milliseconds takes) {
        print->stop();
        klippy_state = "startup";
        state_message = "Klipper is restarting";
        ready_at = Clock::now() + takes;
    }

    // Klipper's own commands for a cartesian printer's skew (klippy's, not the MCU's), under the
    // mutex: the responses, or nullopt for a line the printer runs. Throws as Klipper refuses.
    std::optional<std::vector<std::string>> klippy_command(const std::string& line) {
        const std::string name = first_word(line);
        // PROBE: the printer's probe at the toolhead's place (the twin's G30 answers as Klipper).
        if (name == "PROBE") {
            if (!settings.contains("probe")) throw std::runtime_error("Unknown command:\"PROBE\"");
            return bench->run_printer_line("G30");
        }
        if (name != "SET_SKEW" && name != "SKEW_PROFILE" && name != "SAVE_CONFIG")
            return std::nullopt;
        if (name != "SAVE_CONFIG" && (!cartesian || !settings.contains("skew_correction")))
            throw std::runtime_error("Unknown command:\"" + name + "\"");
        auto p = parameters(line);
        if (name == "SET_SKEW") {
            if (p.count("clear") != 0 && p["clear"] == "1") {
                bench->set_cartesian_skew(0);
                return std::vector<std::string>{};
            }
            double l[3] = {0, 0, 0};
            if (p.count("xy") == 0 ||
                std::sscanf(p["xy"].c_str(), "%lf,%lf,%lf", &l[0], &l[1], &l[2]) != 3)
                throw std::runtime_error(
                    "skew_correction: improperly formatted entry for plane XY");
            bench->set_cartesian_skew(twin_skew_factor(l[0], l[1], l[2]));
            return std::vector<std::string>{};
        }
        if (name == "SKEW_PROFILE") {
            if (p.count("save") != 0) {
                const std::string section = "skew_correction " + p["save"];
                pending[section]["xy_skew"] = repr(bench->cartesian_printer_firmware().xy_skew);
                pending[section]["xz_skew"] = "0.0";
                pending[section]["yz_skew"] = "0.0";
                return std::vector<std::string>{
                    "// Skew Correction state has been saved to profile [" + p["save"] + "]",
                    "// for the current session.  The SAVE_CONFIG command will",
                    "// update the printer config file and restart the printer."};
            }
            if (p.count("load") != 0) {
                const std::string section = "skew_correction " + p["load"];
                if (!settings.contains(section))
                    throw std::runtime_error("skew_correction:  Load failed, unknown profile [" +
                                             p["load"] + "]");
                bench->set_cartesian_skew(settings[section].value("xy_skew", 0.0));
                return std::vector<std::string>{};
            }
            throw std::runtime_error("skew_correction: SKEW_PROFILE needs SAVE= or LOAD=");
        }
        const std::string text = read_whole_file(dir / "printer.cfg");
        write_file_whole(dir / "printer.cfg", saved_config(text, pending));
        restart(std::chrono::milliseconds(300));
        return std::vector<std::string>{};
    }

    // print_stats' state, as Klipper names it.
    std::string print_state() const {
        switch (print->state()) {
            case TwinPrint::State::idle:
                return "standby";
            case TwinPrint::State::printing:
                return "printing";
            case TwinPrint::State::complete:
                return "complete";
            case TwinPrint::State::cancelled:
                return "cancelled";
            case TwinPrint::State::error:
                return "error";
        }
        return "standby";
    }

    bool authorised(const hal::ServerRequest& r) const {
        const std::string wanted = faults.wrong_key ? key + "-rotated" : key;
        const auto it = r.headers.find("x-api-key");
        return it != r.headers.end() && it->second == wanted;
    }

    // The websocket's upgrade: the API key, or a one-shot token (single use, 5 s).
    int upgrade(const hal::ServerRequest& r) {
        if (authorised(r)) return 101;
        const auto at = r.target.find("?token=");
        if (at == std::string::npos) return 401;
        const std::lock_guard lock(mutex);
        const auto token = tokens.find(r.target.substr(at + 7));
        if (token == tokens.end()) return 401;
        const bool valid = Clock::now() < token->second;
        tokens.erase(token);
        if (!valid) return 401;
        ++tokens_redeemed;
        return 101;
    }

    hal::ServerResponse http(const hal::ServerRequest& r) {
        if (!authorised(r)) return http_error(401, "Unauthorized");
        if (r.method == "GET" && r.target == "/access/oneshot_token") {
            const std::lock_guard lock(mutex);
            std::random_device random;
            char token[17];
            std::snprintf(token, sizeof token, "%08x%08x", random(), random());
            tokens[token] = Clock::now() + std::chrono::seconds(5);
            return {200, "application/json", json{{"result", token}}.dump()};
        }
        if (r.method == "GET" && r.target == "/server/files/config/printer.cfg") {
            const std::lock_guard lock(mutex);
            std::string text = read_whole_file(dir / "printer.cfg");
            if (faults.config_edited && !config_read_once) {
                // Someone at the printer changes a value by hand right after the box looked.
                write_file_whole(dir / "printer.cfg", text + "\n# max_z_velocity raised by hand\n");
            }
            config_read_once = true;
            return {200, "text/plain", text};
        }
        if (r.method == "POST" && r.target == "/server/files/upload") {
            const auto content_type =
                r.headers.count("content-type") != 0 ? r.headers.at("content-type") : std::string();
            const auto fields = form_fields(content_type, r.body);
            if (fields.count("file") == 0) return http_error(400, "No file in the upload");
            const std::string root =
                fields.count("root") != 0 ? fields.at("root").second : "gcodes";
            const auto& [name, contents] = fields.at("file");
            if (name.empty() || name.find('/') != std::string::npos || name[0] == '.')
                return http_error(400, "Invalid file name");
            if (root == "config") {
                if (faults.upload_refused) return http_error(400, "Insufficient disk space");
                const std::lock_guard lock(mutex);
                write_file_whole(dir / name, contents);
            } else if (root == "gcodes") {
                std::filesystem::create_directories(dir / "gcodes");
                const std::lock_guard lock(mutex);
                write_file_whole(dir / "gcodes" / name, contents);
            } else {
                return http_error(400, "Invalid root request: " + root);
            }
            return {
                201, "application/json",
                json{{"item", {{"path", name}, {"root", root}}}, {"action", "create_file"}}.dump()};
        }
        return http_error(404, "Not Found");
    }

    // One JSON-RPC request: the messages to send back (G-code responses, then the reply).
    std::vector<std::string> message(const std::string& text) {
        const json request = json::parse(text, nullptr, false);
        if (request.is_discarded() || !request.contains("method")) return {};
        const json id = request.value("id", json());
        const std::string method = request["method"];
        const json params = request.value("params", json::object());
        const int n = count_request();
        // Unanswered: the client's reply timeout ends its wait.
        if (faults.silent_at_request > 0 && n >= faults.silent_at_request) return {};
        if (restarts_at(n) || restarts_on(method, params)) {
            // Klipper comes back with its host.
            const std::lock_guard lock(mutex);
            restart(std::chrono::milliseconds(1500));
            return {};
        }
        const auto reply = [&id](json result) {
            return json{{"jsonrpc", "2.0"}, {"result", std::move(result)}, {"id", id}}.dump();
        };
        std::unique_lock lock(mutex);
        settle();
        if (method == "server.connection.identify") return {reply({{"connection_id", 1}})};
        if (method == "printer.info")
            return {reply({{"state", klippy_state},
                           {"state_message", state_message},
                           {"hostname", "twin"},
                           {"software_version", "v0.12.0-twin"}})};
        if (klippy_state != "ready" && method != "printer.firmware_restart")
            return {rpc_error(id, 503, "Klippy Host not connected").dump()};
        if (method == "printer.firmware_restart") {
            restart(std::chrono::milliseconds(300));
            return {reply("ok")};
        }
        if (method == "printer.gcode.script") {
            if (print->state() == TwinPrint::State::printing)
                return {rpc_error(id, 400, "G-code not allowed while printing").dump()};
            lock.unlock();
            std::vector<std::string> out;
            std::istringstream script(params.value("script", std::string()));
            std::string line;
            while (std::getline(script, line)) {
                try {
                    std::optional<std::vector<std::string>> klippy;
                    {
                        const std::lock_guard again(mutex);
                        klippy = klippy_command(line);
                    }
                    for (const auto& r : klippy ? *klippy : bench->run_printer_line(line))
                        out.push_back(json{
                            {"jsonrpc", "2.0"},
                            {"method", "notify_gcode_response"},
                            {"params",
                             {r}}}.dump());
                } catch (const std::exception& e) {
                    out.push_back(rpc_error(id, 400, e.what()).dump());
                    return out;
                }
            }
            out.push_back(reply("ok"));
            return out;
        }
        if (method == "printer.print.start") {
            const std::string name = params.value("filename", std::string());
            std::string job;
            try {
                job = read_whole_file(dir / "gcodes" / name);
            } catch (const std::exception&) {
                return {rpc_error(id, 400, "File not found: " + name).dump()};
            }
            try {
                print->start(name, job, print_seconds,
                             faults.print_cancelled && print->started() == 0);
            } catch (const std::logic_error& e) {
                return {rpc_error(id, 400, e.what()).dump()};
            }
            return {reply("ok")};
        }
        if (method == "printer.objects.query") {
            json status = json::object();
            const json objects = params.value("objects", json::object());
            for (const auto& [object, fields] : objects.items()) {
                if (object == "print_stats")
                    status[object] = {{"state", print_state()}, {"message", print->message()}};
                else if (object == "configfile")
                    status[object] = {{"settings", settings}};
                else
                    status[object] = json::object();
            }
            return {reply({{"eventtime", 1.0}, {"status", status}})};
        }
        return {rpc_error(id, -32601, "Method not found").dump()};
    }
};

MoonrakerTwin::MoonrakerTwin(std::shared_ptr<TwinBench> bench, std::filesystem::path host_dir,
                             TwinHostSettings settings)
    : state_(std::make_unique<State>(std::move(bench), std::move(host_dir), std::move(settings))) {
    auto& s = *state_;
    const auto& machine = s.bench->scenario().machine;
    s.cartesian = machine.kind == "cartesian";
    if (!std::filesystem::exists(s.dir / "printer.cfg"))
        write_file_whole(
            s.dir / "printer.cfg",
            s.cartesian ? printer_cfg_of_cartesian(machine.bed_size_x_mm, machine.bed_size_y_mm)
                        : printer_cfg_of(s.bench->delta_printer_firmware(), s.print_radius_mm));
    s.first_config = read_whole_file(s.dir / "printer.cfg");
    s.load_config();
    if (s.faults.printer_not_ready) {
        s.klippy_state = "startup";
        s.state_message = "mcu 'mcu': Unable to connect";
    }
    s.server = std::make_unique<drivers::HttpServer>(
        "127.0.0.1", 0,
        drivers::HttpServer::Handlers{
            [&s](const hal::ServerRequest& r) { return s.http(r); },
            [&s](const hal::ServerRequest& r) { return s.upgrade(r); },
            [&s](const hal::ServerRequest&, const std::string& m) { return s.message(m); }});
}

MoonrakerTwin::~MoonrakerTwin() {
    state_->shut_down();
}

int MoonrakerTwin::tokens_redeemed() const {
    const std::lock_guard lock(state_->mutex);
    return state_->tokens_redeemed;
}

std::string MoonrakerTwin::url() const {
    return state_->url();
}

}  // namespace calbox::sim
