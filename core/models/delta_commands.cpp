#include "core/models/delta_commands.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "core/targets/gcode_line.hpp"

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

std::vector<std::string> firmware_commands(const std::string& firmware, const DeltaGeometry& g) {
    if (firmware == "marlin") return marlin_commands(g);
    if (firmware == "rrf") return rrf_commands(g);
    if (firmware == "klipper") return klipper_snippet(g);
    throw std::invalid_argument("no delta commands for firmware '" + firmware +
                                "' (marlin, rrf or klipper)");
}

std::vector<std::string> marlin_settings_from_report(const std::vector<std::string>& replies) {
    std::vector<std::string> out;
    for (const auto& reply : replies) {
        std::string_view text = reply;
        if (text.substr(0, 5) == "echo:") text.remove_prefix(5);
        while (!text.empty() && text.front() == ' ') text.remove_prefix(1);
        if (text.substr(0, 5) == "M665 " || text.substr(0, 5) == "M666 ") out.emplace_back(text);
    }
    return out;
}

std::string settings_mismatch(const std::vector<std::string>& sent,
                              const std::vector<std::string>& reported) {
    constexpr double kPrintedPrecision = 0.0015;  // Marlin prints three decimals
    for (const auto& command : sent) {
        gcode::Line want;
        try {
            want = gcode::parse_line(command);
        } catch (const gcode::SyntaxError&) {
            continue;
        }
        if (!want.is('M', 665) && !want.is('M', 666)) continue;
        const std::string name = want.is('M', 665) ? "M665" : "M666";
        const gcode::Line* got = nullptr;
        gcode::Line parsed;
        for (const auto& r : reported) {
            parsed = gcode::parse_line(r);
            if (parsed.is('M', want.command_number)) {
                got = &parsed;
                break;
            }
        }
        if (got == nullptr) return "the printer does not report " + name;
        for (const auto& w : want.parameters) {
            const auto v = got->value(w.letter);
            if (!w.value) continue;
            if (!v || std::abs(*v - *w.value) > kPrintedPrecision) {
                char why[160];
                std::snprintf(why, sizeof why, "%s %c sent %.3f, the printer reports %s",
                              name.c_str(), w.letter, *w.value,
                              v ? std::to_string(*v).c_str() : "nothing");
                return why;
            }
        }
    }
    return "";
}

}  // namespace calbox::models
