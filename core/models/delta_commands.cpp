#include "core/models/delta_commands.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "core/gcode/gcode_line.hpp"
#include "core/models/klipper_config.hpp"

namespace calbox::models {
namespace {

std::string f3(double v) {
    char b[64];
    std::snprintf(b, sizeof b, "%.3f", v == 0 ? 0.0 : v);  // never "-0.000"
    if (std::string(b) == "-0.000") return "0.000";
    return b;
}

}  // namespace

std::vector<std::string> marlin_commands(const DeltaGeometry& g0) {
    const DeltaGeometry g = in_gauge(g0);
    return {"M665 L" + f3(g.diagonal_rod_mm) + " R" + f3(g.radius_mm) + " H" + f3(g.height_mm) +
                " X" + f3(g.tower_angle_trim_deg[0]) + " Y" + f3(g.tower_angle_trim_deg[1]) + " Z" +
                f3(g.tower_angle_trim_deg[2]) + " A" + f3(g.diagonal_rod_trim_mm[0]) + " B" +
                f3(g.diagonal_rod_trim_mm[1]) + " C" + f3(g.diagonal_rod_trim_mm[2]),
            "M666 X" + f3(g.endstop_offset_mm[0]) + " Y" + f3(g.endstop_offset_mm[1]) + " Z" +
                f3(g.endstop_offset_mm[2]),
            "M500"};
}

std::vector<std::string> rrf_commands(const DeltaGeometry& g) {
    const RrfDelta r = to_rrf(in_gauge(g));
    return {"M665 L" + f3(r.diagonal_mm[0]) + ":" + f3(r.diagonal_mm[1]) + ":" +
                f3(r.diagonal_mm[2]) + " R" + f3(r.radius_mm) + " H" + f3(r.height_mm) + " X" +
                f3(r.x_tower_angle_deg) + " Y" + f3(r.y_tower_angle_deg) + " Z0.000",
            "M666 X" + f3(r.endstop_adjustment_mm[0]) + " Y" + f3(r.endstop_adjustment_mm[1]) +
                " Z" + f3(r.endstop_adjustment_mm[2]),
            "M500"};
}

std::vector<std::string> klipper_snippet(const DeltaGeometry& g) {
    const KlipperDelta k = to_klipper(in_gauge(g));
    std::vector<std::string> out{"[printer]", "delta_radius: " + f3(k.delta_radius_mm)};
    const char* steppers[3] = {"[stepper_a]", "[stepper_b]", "[stepper_c]"};
    for (std::size_t i = 0; i < 3; ++i) {
        out.emplace_back(steppers[i]);
        out.push_back("arm_length: " + f3(k.arm_length_mm[i]));
        out.push_back("angle: " + f3(k.angle_deg[i]));
        out.push_back("position_endstop: " + f3(k.position_endstop_mm[i]));
    }
    return out;
}

std::string klipper_saved_config(const std::string& printer_cfg, const DeltaGeometry& g) {
    const KlipperDelta k = to_klipper(in_gauge(g));
    std::vector<KlipperSavedValue> values{{"printer", "delta_radius", f3(k.delta_radius_mm)}};
    const char* steppers[3] = {"stepper_a", "stepper_b", "stepper_c"};
    for (std::size_t i = 0; i < 3; ++i) {
        values.push_back({steppers[i], "angle", f3(k.angle_deg[i])});
        values.push_back({steppers[i], "arm_length", f3(k.arm_length_mm[i])});
        values.push_back({steppers[i], "position_endstop", f3(k.position_endstop_mm[i])});
    }
    return klipper_saved_values(printer_cfg, values);
}

std::string klipper_settings_mismatch(const DeltaGeometry& sent, const DeltaGeometry& in_force) {
    const KlipperDelta a = to_klipper(in_gauge(sent));
    const KlipperDelta b = to_klipper(in_gauge(in_force));
    // Sent to 3 decimals: the last digit's rounding, and the gauge's sums, within 1.5 of it.
    constexpr double kTolerance = 0.0015;
    const auto differ = [](double x, double y) { return std::abs(x - y) > kTolerance; };
    if (differ(a.delta_radius_mm, b.delta_radius_mm))
        return "[printer] delta_radius sent " + f3(a.delta_radius_mm) + ", in force " +
               f3(b.delta_radius_mm);
    const char* steppers[3] = {"[stepper_a]", "[stepper_b]", "[stepper_c]"};
    for (std::size_t i = 0; i < 3; ++i) {
        const std::pair<const char*, std::pair<double, double>> values[] = {
            {"arm_length", {a.arm_length_mm[i], b.arm_length_mm[i]}},
            {"angle", {a.angle_deg[i], b.angle_deg[i]}},
            {"position_endstop", {a.position_endstop_mm[i], b.position_endstop_mm[i]}}};
        for (const auto& [key, pair] : values)
            if (differ(pair.first, pair.second))
                return std::string(steppers[i]) + " " + key + " sent " + f3(pair.first) +
                       ", in force " + f3(pair.second);
    }
    return {};
}

std::vector<std::string> firmware_commands(const std::string& firmware, const DeltaGeometry& g) {
    if (firmware == "marlin") return marlin_commands(g);
    if (firmware == "rrf") return rrf_commands(g);
    if (firmware == "klipper") return klipper_snippet(g);
    throw std::invalid_argument("no delta commands for firmware '" + firmware +
                                "' (marlin, rrf or klipper)");
}

std::vector<std::string> settings_query(const std::string& firmware) {
    if (firmware == "marlin") return {"M503"};
    if (firmware == "rrf") return {"M665", "M666"};
    throw std::invalid_argument("the delta settings of firmware '" + firmware +
                                "' cannot be read over the link (marlin or rrf)");
}

namespace {

// The number (or ':' list) at the start of `text`, as printed; empty when there is none.
std::string_view leading_number(std::string_view text) {
    std::size_t n = 0;
    while (n < text.size() &&
           (std::isdigit(static_cast<unsigned char>(text[n])) != 0 || text[n] == '.' ||
            text[n] == '-' || text[n] == '+' || text[n] == ':'))
        ++n;
    return text.substr(0, n);
}

// Appends " <letter><number>" for the number printed right after `key` in `text`, if any.
void append_word_after(std::string& command, std::string_view text, std::string_view key,
                       char letter) {
    const std::size_t at = text.find(key);
    if (at == std::string_view::npos) return;
    const auto number = leading_number(text.substr(at + key.size()));
    if (number.empty()) return;
    command += ' ';
    command += letter;
    command += number;
}

// RepRapFirmware 3's M665 report: "Diagonals 250.000:250.000:250.000, delta radius 140.000,
// homed height 300.000, bed radius 85.0, X 0.000°, Y 0.000°, Z 0.000°" ("Diagonal 250.000" with
// one rod length).
std::string rrf_m665_from_report(std::string_view text) {
    static constexpr std::pair<std::string_view, char> kFields[] = {{"Diagonals ", 'L'},
                                                                    {"Diagonal ", 'L'},
                                                                    {"delta radius ", 'R'},
                                                                    {"homed height ", 'H'},
                                                                    {"bed radius ", 'B'},
                                                                    {"X ", 'X'},
                                                                    {"Y ", 'Y'},
                                                                    {"Z ", 'Z'}};
    std::string command = "M665";
    while (!text.empty()) {
        const std::size_t comma = std::min(text.find(','), text.size());
        std::string_view field = text.substr(0, comma);
        text.remove_prefix(std::min(comma + 1, text.size()));
        while (!field.empty() && field.front() == ' ') field.remove_prefix(1);
        for (const auto& [name, letter] : kFields) {
            if (!field.starts_with(name)) continue;
            append_word_after(command, field, name, letter);
            break;
        }
    }
    return command;
}

// "Endstop adjustments X0.00 Y0.00 Z0.00, tilt X0.00% Y0.00%": M666 X Y Z, and the bed tilt as
// M666 A B (percent).
std::string rrf_m666_from_report(std::string_view text) {
    std::string command = "M666";
    const std::size_t tilt = std::min(text.find("tilt "), text.size());
    const std::string_view adjustments = text.substr(0, tilt), tilts = text.substr(tilt);
    for (const char letter : {'X', 'Y', 'Z'})
        append_word_after(command, adjustments, std::string{' ', letter}, letter);
    append_word_after(command, tilts, "X", 'A');
    append_word_after(command, tilts, "Y", 'B');
    return command;
}

// Marlin's M503 prints M665 and M666 as they are typed, behind "echo:".
std::vector<std::string> marlin_settings_reported(const std::vector<std::string>& replies) {
    std::vector<std::string> out;
    for (const auto& reply : replies) {
        std::string_view text = reply;
        if (text.starts_with("echo:")) text.remove_prefix(5);
        while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
        if (text.starts_with("M665 ") || text.starts_with("M666 ")) out.emplace_back(text);
    }
    return out;
}

// RepRapFirmware's M665 and M666 answer in words: written back as the commands.
std::vector<std::string> rrf_settings_reported(const std::vector<std::string>& replies) {
    std::string m665, m666;
    for (const auto& reply : replies) {
        if (reply.starts_with("Diagonal")) m665 = rrf_m665_from_report(reply);
        if (reply.starts_with("Endstop adjustments")) m666 = rrf_m666_from_report(reply);
    }
    std::vector<std::string> out;
    if (!m665.empty()) out.push_back(m665);
    if (!m666.empty()) out.push_back(m666);
    return out;
}

}  // namespace

std::vector<std::string> settings_from_report(const std::string& firmware,
                                              const std::vector<std::string>& replies) {
    if (firmware == "marlin") return marlin_settings_reported(replies);
    if (firmware == "rrf") return rrf_settings_reported(replies);
    throw std::invalid_argument("no settings report for firmware '" + firmware + "'");
}

DeltaGeometry geometry_from_settings(const std::string& firmware,
                                     const std::vector<std::string>& commands) {
    std::optional<gcode::Line> m665, m666;
    for (const auto& c : commands) {
        auto line = gcode::parse_line(c);
        if (line.is('M', 665))
            m665 = std::move(line);
        else if (line.is('M', 666))
            m666 = std::move(line);
    }
    if (!m665 || !m666)
        throw std::invalid_argument(std::string("the printer's settings lack ") +
                                    (m665 ? "M666" : "M665"));
    for (const char letter : {'L', 'R', 'H'})
        if (!m665->value(letter))
            throw std::invalid_argument(std::string("the printer's M665 lacks ") + letter);
    const auto get = [](const gcode::Line& line, char letter) {
        return line.value(letter).value_or(0);
    };
    if (firmware == "marlin") {
        DeltaGeometry g;
        g.diagonal_rod_mm = get(*m665, 'L');
        g.radius_mm = get(*m665, 'R');
        g.height_mm = get(*m665, 'H');
        for (std::size_t i = 0; i < 3; ++i) {
            g.tower_angle_trim_deg[i] = get(*m665, "XYZ"[i]);
            g.diagonal_rod_trim_mm[i] = get(*m665, "ABC"[i]);
            g.endstop_offset_mm[i] = get(*m666, "XYZ"[i]);
        }
        return in_gauge(g);
    }
    if (firmware == "rrf") {
        RrfDelta r;
        const auto rods = m665->values('L');
        for (std::size_t i = 0; i < 3; ++i) {
            r.diagonal_mm[i] = rods[std::min(i, rods.size() - 1)];
            r.endstop_adjustment_mm[i] = get(*m666, "XYZ"[i]);
        }
        r.radius_mm = get(*m665, 'R');
        r.height_mm = get(*m665, 'H');
        // RepRapFirmware takes a Z tower angle too; only the differences are geometry.
        r.x_tower_angle_deg = get(*m665, 'X') - get(*m665, 'Z');
        r.y_tower_angle_deg = get(*m665, 'Y') - get(*m665, 'Z');
        return from_rrf(r);
    }
    throw std::invalid_argument("no settings commands for firmware '" + firmware + "'");
}

namespace {

// The first of the reported lines that is command M`number`.
std::optional<gcode::Line> reported_command(const std::vector<std::string>& reported, int number) {
    for (const auto& r : reported) {
        auto parsed = gcode::parse_line(r);
        if (parsed.is('M', number)) return parsed;
    }
    return std::nullopt;
}

// The first word whose value `got` does not report within `tolerance`, in one line; "" for none.
std::string word_mismatch(const gcode::Line& want, const gcode::Line& got, const std::string& name,
                          double tolerance) {
    for (const auto& w : want.parameters) {
        const auto sent = want.values(w.letter);
        if (sent.empty()) continue;
        const auto have = got.values(w.letter);
        for (std::size_t i = 0; i < std::max(sent.size(), have.size()); ++i) {
            // One value stands for all: RepRapFirmware's "L250" is every tower's rod.
            const double sent_value = sent[std::min(i, sent.size() - 1)];
            if (!have.empty() &&
                std::abs(have[std::min(i, have.size() - 1)] - sent_value) <= tolerance)
                continue;
            char why[160];
            std::snprintf(
                why, sizeof why, "%s %c sent %.3f, the printer reports %s", name.c_str(), w.letter,
                sent_value,
                have.empty() ? "nothing" : f3(have[std::min(i, have.size() - 1)]).c_str());
            return why;
        }
    }
    return "";
}

}  // namespace

std::string settings_mismatch(const std::string& firmware, const std::vector<std::string>& sent,
                              const std::vector<std::string>& reported) {
    for (const auto& command : sent) {
        gcode::Line want;
        try {
            want = gcode::parse_line(command);
        } catch (const gcode::SyntaxError&) {
            continue;
        }
        if (!want.is('M', 665) && !want.is('M', 666)) continue;
        const std::string name = want.is('M', 665) ? "M665" : "M666";
        const auto got = reported_command(reported, want.command_number);
        if (!got) return "the printer does not report " + name;
        // A unit and a half of the last digit printed: rounding on both sides, and the
        // firmware's float.
        const double tolerance = firmware == "rrf" && want.command_number == 666 ? 0.015 : 0.0015;
        if (auto why = word_mismatch(want, *got, name, tolerance); !why.empty()) return why;
    }
    return "";
}

}  // namespace calbox::models
