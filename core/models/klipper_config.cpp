#include "core/models/klipper_config.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "core/geometry/types.hpp"
#include "core/models/machine_import.hpp"
#include "core/trimmed_text.hpp"

namespace calbox::models {
namespace {

constexpr std::string_view kSaveConfigMark = "#*#";
constexpr const char* kSaveConfigHeader =
    "#*# <---------------------- SAVE_CONFIG ---------------------->\n"
    "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n"
    "#*#\n";

// The SAVE_CONFIG block's sections in their order, each its keys and values in theirs.
struct SavedSection {
    std::string name;
    std::vector<std::pair<std::string, std::string>> values;
};

void set_value(std::vector<SavedSection>& sections, const KlipperSavedValue& v) {
    auto it = std::find_if(sections.begin(), sections.end(),
                           [&](const SavedSection& s) { return s.name == v.section; });
    if (it == sections.end()) it = sections.insert(sections.end(), SavedSection{v.section, {}});
    for (auto& [key, value] : it->values)
        if (key == v.key) {
            value = v.value;
            return;
        }
    it->values.emplace_back(v.key, v.value);
}

std::string fixed(const char* format, double v) {
    char b[64];
    std::snprintf(b, sizeof b, format, v);
    return b;
}

// The SAVE_CONFIG block's sections, parsed; what is above it kept byte for byte in `above`.
std::vector<SavedSection> saved_block_of(const std::string& printer_cfg, std::string& above) {
    std::vector<SavedSection> sections;
    bool in_block = false;
    std::size_t at = 0;
    while (at < printer_cfg.size()) {
        std::size_t end = printer_cfg.find('\n', at);
        end = end == std::string::npos ? printer_cfg.size() : end + 1;
        const std::string_view raw(printer_cfg.data() + at, end - at);
        at = end;
        const bool marked = raw.substr(0, kSaveConfigMark.size()) == kSaveConfigMark;
        if (!in_block && !marked) {
            above.append(raw);
            continue;
        }
        in_block = true;
        if (!marked)
            throw std::invalid_argument(
                "printer.cfg: a line below the SAVE_CONFIG block's start does not begin with #*#");
        const std::string line = trimmed(raw.substr(kSaveConfigMark.size()));
        if (line.empty() || line.find("SAVE_CONFIG") != std::string::npos ||
            line.rfind("DO NOT EDIT", 0) == 0)
            continue;
        if (line.front() == '[' && line.back() == ']') {
            sections.push_back({trimmed(std::string_view(line).substr(1, line.size() - 2)), {}});
            continue;
        }
        const std::size_t sep = line.find_first_of("=:");
        if (sections.empty() || sep == std::string::npos)
            throw std::invalid_argument("printer.cfg: SAVE_CONFIG block line '" + line +
                                        "' is not a section or a key = value");
        sections.back().values.emplace_back(trimmed(std::string_view(line).substr(0, sep)),
                                            trimmed(std::string_view(line).substr(sep + 1)));
    }
    return sections;
}

}  // namespace

std::string klipper_saved_values(const std::string& printer_cfg,
                                 const std::vector<KlipperSavedValue>& values) {
    std::string above;
    std::vector<SavedSection> sections = saved_block_of(printer_cfg, above);
    for (const auto& v : values) set_value(sections, v);
    // SAVE_CONFIG leaves one blank line between the file's body and its block.
    while (!above.empty() && (above.back() == '\n' || above.back() == ' ')) above.pop_back();
    std::string out = above + (above.empty() ? "" : "\n\n") + kSaveConfigHeader;
    for (std::size_t i = 0; i < sections.size(); ++i) {
        if (i > 0) out += "#*#\n";
        out += "#*# [" + sections[i].name + "]\n";
        for (const auto& [key, value] : sections[i].values)
            out.append("#*# ").append(key).append(" = ").append(value).append("\n");
    }
    return out;
}

std::optional<double> klipper_probe_z_offset(const std::string& source, const std::string& text) {
    std::vector<std::string> notes;
    const auto sections = read_klipper_sections(
        source, text, [](const std::string&) { return std::optional<std::string>{}; }, notes);
    for (const char* name : {"probe", "bltouch"}) {
        const auto s = sections.find(name);
        if (s == sections.end()) continue;
        const auto v = s->second.find("z_offset");
        if (v == s->second.end()) continue;
        char* end = nullptr;
        const double z = std::strtod(v->second.c_str(), &end);
        if (end == v->second.c_str() || *end != '\0' || !std::isfinite(z))
            throw ImportError(source + ": [" + name + "] z_offset '" + v->second +
                              "' is not a number");
        return z;
    }
    return std::nullopt;
}

KlipperCartesian read_klipper_cartesian(const std::string& source, const std::string& text) {
    std::vector<std::string> notes;
    const auto sections = read_klipper_sections(
        source, text, [](const std::string&) { return std::optional<std::string>{}; }, notes);
    const auto value = [&](const std::string& section,
                           const std::string& key) -> std::optional<std::string> {
        const auto s = sections.find(section);
        if (s == sections.end()) return std::nullopt;
        const auto k = s->second.find(key);
        if (k == s->second.end()) return std::nullopt;
        return k->second;
    };
    const auto number = [&](const std::string& section, const std::string& key) {
        const auto v = value(section, key);
        if (!v) throw ImportError(source + ": no " + key + " in [" + section + "]");
        char* end = nullptr;
        const double n = std::strtod(v->c_str(), &end);
        if (end == v->c_str() || *end != '\0' || !std::isfinite(n))
            throw ImportError(source + ": [" + section + "] " + key + " '" + *v +
                              "' is not a number");
        return n;
    };
    const auto kinematics = value("printer", "kinematics");
    if (!kinematics) throw ImportError(source + ": no [printer] kinematics");
    // Each axis its own motor: a corexy's stepper_x and stepper_y each move both axes.
    if (*kinematics != "cartesian")
        throw ImportError(source + ": kinematics is '" + *kinematics +
                          "', not cartesian: calbox sets a cartesian Klipper printer's travel "
                          "and skew");
    KlipperCartesian k;
    k.rotation_distance_x_mm = number("stepper_x", "rotation_distance");
    k.rotation_distance_y_mm = number("stepper_y", "rotation_distance");
    if (!(k.rotation_distance_x_mm > 0) || !(k.rotation_distance_y_mm > 0))
        throw ImportError(source + ": a rotation_distance is not positive");
    const std::string profile = std::string("skew_correction ") + kKlipperSkewProfile;
    if (value(profile, "xy_skew")) k.xy_skew = number(profile, "xy_skew");
    k.takes_skew = sections.count("skew_correction") != 0;
    return k;
}

KlipperCartesian klipper_cartesian_corrected(const KlipperCartesian& now, double scale_x,
                                             double scale_y, double skew) {
    // Commanded (x, y) leaves Klipper as (x - k0 y, y), each axis then travelling g = 1 + s times
    // that: the tool lands at (gx x - gx k0 y + gy L y, gy y) on axes that lean by L. The fit saw
    // scale_x = gx - 1, scale_y = gy - 1 and skew = gy L - gx k0: the lean L is the new k.
    KlipperCartesian out = now;
    const double gx = 1 + scale_x, gy = 1 + scale_y;
    out.rotation_distance_x_mm = now.rotation_distance_x_mm * gx;
    out.rotation_distance_y_mm = now.rotation_distance_y_mm * gy;
    out.xy_skew = (skew + now.xy_skew.value_or(0) * gx) / gy;
    return out;
}

std::vector<std::string> klipper_skew_commands(double xy_skew) {
    constexpr double kSide = 100;
    const geometry::Point2 a{0, 0}, b{kSide, 0}, c{kSide + xy_skew * kSide, kSide},
        d{xy_skew * kSide, kSide};
    return {"SET_SKEW XY=" + fixed("%.6f", geometry::distance(a, c)) + "," +
                fixed("%.6f", geometry::distance(b, d)) + "," +
                fixed("%.6f", geometry::distance(a, d)),
            std::string("SKEW_PROFILE SAVE=") + kKlipperSkewProfile};
}

std::vector<KlipperSavedValue> klipper_travel_values(const KlipperCartesian& k) {
    return {{"stepper_x", "rotation_distance", fixed("%.6f", k.rotation_distance_x_mm)},
            {"stepper_y", "rotation_distance", fixed("%.6f", k.rotation_distance_y_mm)}};
}

bool klipper_changed_only_travel_and_skew(const std::string& before, const std::string& now) {
    // Above the SAVE_CONFIG block, line for line, but for the '#' SAVE_CONFIG puts before a line
    // its block now sets (and the blank lines it trims before the block).
    const auto above = [](const std::string& text) {
        std::vector<std::string> lines;
        std::size_t at = 0;
        while (at < text.size()) {
            std::size_t end = text.find('\n', at);
            if (end == std::string::npos) end = text.size();
            std::string line = text.substr(at, end - at);
            at = end + 1;
            if (line.rfind(kSaveConfigMark, 0) == 0) break;
            if (!line.empty() && line.front() == '#') line.erase(0, 1);
            lines.push_back(trimmed(line));
        }
        while (!lines.empty() && lines.back().empty()) lines.pop_back();
        return lines;
    };
    if (above(before) != above(now)) return false;
    // And the settings Klipper reads, the box's own left out.
    const auto others = [](const std::string& text) {
        std::vector<std::string> notes;
        auto sections = read_klipper_sections(
            "printer.cfg", text, [](const std::string&) { return std::optional<std::string>{}; },
            notes);
        sections.erase(std::string("skew_correction ") + kKlipperSkewProfile);
        for (const char* stepper : {"stepper_x", "stepper_y"})
            sections[stepper].erase("rotation_distance");
        return sections;
    };
    return others(before) == others(now);
}

std::string klipper_cartesian_mismatch(const KlipperCartesian& sent,
                                       const KlipperCartesian& in_force) {
    // Sent to 6 decimals: the last digit's rounding within 1.5 of it.
    constexpr double kDistanceTolerance = 1.5e-6, kSkewTolerance = 1e-6;
    const auto differ = [](const char* what, double a, double b, double tolerance) {
        if (std::abs(a - b) <= tolerance) return std::string();
        return std::string(what) + " sent " + fixed("%.6f", a) + ", in force " + fixed("%.6f", b);
    };
    if (auto d = differ("[stepper_x] rotation_distance", sent.rotation_distance_x_mm,
                        in_force.rotation_distance_x_mm, kDistanceTolerance);
        !d.empty())
        return d;
    if (auto d = differ("[stepper_y] rotation_distance", sent.rotation_distance_y_mm,
                        in_force.rotation_distance_y_mm, kDistanceTolerance);
        !d.empty())
        return d;
    if (sent.xy_skew.has_value() != in_force.xy_skew.has_value())
        return std::string("[skew_correction ") + kKlipperSkewProfile + "] is " +
               (sent.xy_skew ? "missing" : "there, not sent");
    if (sent.xy_skew) return differ("xy_skew", *sent.xy_skew, *in_force.xy_skew, kSkewTolerance);
    return {};
}

}  // namespace calbox::models
