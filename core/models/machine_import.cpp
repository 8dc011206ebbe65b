#include "core/models/machine_import.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>

#include "core/gcode/gcode_line.hpp"
#include "core/number_text.hpp"
#include "core/trimmed_text.hpp"

namespace calbox::models {
namespace {

std::vector<std::string> lines_of(std::string_view text) {
    std::vector<std::string> out;
    std::size_t start = 0;
    while (start <= text.size()) {
        const auto end = std::min(text.find('\n', start), text.size());
        std::string line(text.substr(start, end - start));
        if (!line.empty() && line.back() == '\r') line.pop_back();
        out.push_back(std::move(line));
        start = end + 1;
    }
    return out;
}

// The G-code command starting at `word` in a console line ("echo:  M665 L250.00 ..."), its
// comment cut off; empty when the line holds none.
std::optional<gcode::Line> command_in(const std::string& line, std::string_view word) {
    std::size_t at = 0;
    while ((at = line.find(word, at)) != std::string::npos) {
        const bool starts = at == 0 || line[at - 1] == ' ' || line[at - 1] == ':';
        const std::size_t after = at + word.size();
        const bool ends = after == line.size() || line[after] == ' ';
        if (starts && ends) {
            std::string command = line.substr(at);
            command = command.substr(0, command.find(';'));
            try {
                return gcode::parse_line(command);
            } catch (const gcode::SyntaxError&) {
                return std::nullopt;
            }
        }
        at = after;
    }
    return std::nullopt;
}

double required(const std::optional<double>& v, const std::string& what) {
    if (!v) throw ImportError(what);
    return *v;
}

double parse_number(const std::string& text, const std::string& what) {
    const std::string t = trimmed(text);
    char* end = nullptr;
    const double v = std::strtod(t.c_str(), &end);
    if (t.empty() || end != t.c_str() + t.size())
        throw ImportError(what + " is not a number: '" + t + "'");
    return v;
}

std::string number_toml(double v) {
    std::string s = number_text("%.6f", v);
    while (!s.empty() && s.back() == '0') s.pop_back();
    if (!s.empty() && s.back() == '.') s += '0';
    return s;
}

std::string triple_toml(const std::array<double, 3>& v) {
    // Appended in place: GCC 12 at -O3 misreads `"[" + std::string` as an overlapping copy
    // (-Werror=restrict), the release preset's stop.
    std::string text = "[";
    for (std::size_t k = 0; k < v.size(); ++k) {
        if (k > 0) text += ", ";
        text += number_toml(v[k]);
    }
    text += ']';
    return text;
}

// A delta machine file's [machine] part: the printable radius from the files, the options, or
// defaulted with a note.
ImportedMachine delta_machine(const std::string& firmware, const DeltaGeometry& geometry,
                              std::optional<double> bed_radius_mm, const std::string& radius_from,
                              const ImportOptions& options) {
    // The files' own figures refused as what they are, before anything is derived from them.
    const std::string radius_word =
        firmware == "klipper" ? "delta_radius" : "the delta radius (M665 R)";
    if (!(geometry.radius_mm > 0))
        throw ImportError(radius_word + " " + number_toml(geometry.radius_mm) +
                          ": not a radius (it must be above 0)");
    if (!(geometry.diagonal_rod_mm > geometry.radius_mm))
        throw ImportError("the diagonal rod " + number_toml(geometry.diagonal_rod_mm) +
                          " mm is not longer than " + radius_word + " " +
                          number_toml(geometry.radius_mm) + " mm: no delta printer is built so");
    ImportedMachine out;
    out.machine.kind = "delta";
    out.machine.firmware = firmware;
    out.machine.delta = geometry;
    if (options.bed_radius_mm) {
        out.machine.bed_radius_mm = *options.bed_radius_mm;
    } else if (bed_radius_mm) {
        out.machine.bed_radius_mm = *bed_radius_mm;
        out.notes.push_back("bed_radius_mm " + number_toml(*bed_radius_mm) + " from " +
                            radius_from);
    } else {
        out.machine.bed_radius_mm = std::round(0.6 * geometry.radius_mm);
        out.notes.push_back("bed_radius_mm: not in the files; " +
                            number_toml(out.machine.bed_radius_mm) +
                            " (0.6 of the delta radius) assumed, give --bed-radius");
    }
    out.notes.emplace_back(
        "not in the files, left to the defaults: the line width, layer height and filament "
        "(0.45, 0.2, 1.75 mm), the bed's material and temperatures; the camera is set up by "
        "the box");
    return out;
}

}  // namespace

std::optional<double> number_after(std::string_view text, std::string_view key, std::size_t from) {
    const auto at = text.find(key, from);
    if (at == std::string_view::npos) return std::nullopt;
    // strtod reads a terminated string: the rest of the line, copied.
    const std::string rest(text.substr(at + key.size()));
    char* end = nullptr;
    const double v = std::strtod(rest.c_str(), &end);
    if (end == rest.c_str() || !std::isfinite(v)) return std::nullopt;
    return v;
}

MarlinCapture read_marlin_capture(std::string_view log) {
    MarlinCapture capture;
    const auto delta = [&]() -> MarlinDeltaSettings& {
        if (!capture.delta) capture.delta.emplace();
        return *capture.delta;
    };
    // M666 and G33's report both set the endstops, the last in the log in force. M666 alone is
    // no delta's: a cartesian with dual endstops adjusts them with it too.
    std::array<double, 3> endstop_mm{};
    bool m666_seen = false;
    for (const auto& line : lines_of(log)) {
        if (const auto m665 = command_in(line, "M665")) {
            auto& d = delta();
            if (auto v = m665->value('L')) d.rod_mm = v;
            if (auto v = m665->value('R')) d.radius_mm = v;
            if (auto v = m665->value('H')) d.height_mm = v;
            for (std::size_t i = 0; i < 3; ++i) {
                if (auto v = m665->value("XYZ"[i])) d.angle_trim_deg[i] = *v;
                if (auto v = m665->value("ABC"[i])) d.rod_trim_mm[i] = *v;
            }
        } else if (const auto m666 = command_in(line, "M666")) {
            m666_seen = true;
            for (std::size_t i = 0; i < 3; ++i)
                if (auto v = m666->value("XYZ"[i])) endstop_mm[i] = *v;
        } else if (const auto m92 = command_in(line, "M92")) {
            if (m92->has('T')) continue;  // an extruder's steps
            if (auto x = m92->value('X'), y = m92->value('Y'); x && y)
                capture.steps_per_mm_xy = std::array<double, 2>{*x, *y};
        } else if (line.find(".Height:") != std::string::npos) {
            // G33's report of what it set: ".Height:297.80  Ex:-0.14  Ey:-0.07  Ez:+0.00
            // Radius:100.79"; the last report is what is in force.
            auto& d = delta();
            d.from_g33 = true;
            if (auto v = number_after(line, ".Height:")) d.height_mm = v;
            if (auto v = number_after(line, "Radius:")) d.radius_mm = v;
            for (std::size_t i = 0; i < 3; ++i)
                if (auto v = number_after(line, std::string("E") + "xyz"[i] + ":"))
                    endstop_mm[i] = *v;
        } else if (line.find(".Tower angle") != std::string::npos) {
            auto& d = delta();
            for (std::size_t i = 0; i < 3; ++i)
                if (auto v = number_after(line, std::string("T") + "xyz"[i] + ":"))
                    d.angle_trim_deg[i] = *v;
        }
    }
    if (capture.delta) capture.delta->endstop_mm = endstop_mm;
    capture.dual_endstops = m666_seen && !capture.delta;
    return capture;
}

ImportedMachine import_marlin(std::string_view log, const ImportOptions& options) {
    const MarlinCapture capture = read_marlin_capture(log);
    if (capture.delta) {
        const auto& d = *capture.delta;
        DeltaGeometry g;
        if (options.diagonal_rod_mm) {
            g.diagonal_rod_mm = *options.diagonal_rod_mm;
        } else {
            g.diagonal_rod_mm = required(
                d.rod_mm, "the capture does not give the diagonal rod (M665 L)" +
                              std::string(d.from_g33 ? ": G33's report leaves it out" : "") +
                              "; give --diagonal-rod MM, or capture M503");
        }
        g.radius_mm = required(d.radius_mm, "the capture does not give the delta radius (M665 R)");
        g.height_mm = required(d.height_mm, "the capture does not give the height (M665 H)");
        g.tower_angle_trim_deg = d.angle_trim_deg;
        g.diagonal_rod_trim_mm = d.rod_trim_mm;
        g.endstop_offset_mm = d.endstop_mm;
        auto out = delta_machine("marlin", in_gauge(g), std::nullopt, "", options);
        out.notes.insert(out.notes.begin(),
                         std::string("the delta geometry from ") +
                             (d.from_g33 ? "G33's last report" : "M665 and M666") +
                             (options.diagonal_rod_mm ? ", the rod from --diagonal-rod" : ""));
        return out;
    }
    if (capture.steps_per_mm_xy) {
        ImportedMachine out;
        out.machine.kind = "cartesian";
        out.machine.firmware = "marlin";
        out.machine.planar.emplace();
        out.machine.planar->holes = "light";
        out.machine.planar->steps_per_mm_x = (*capture.steps_per_mm_xy)[0];
        out.machine.planar->steps_per_mm_y = (*capture.steps_per_mm_xy)[1];
        out.notes.emplace_back("a cartesian printer: steps per mm from M92");
        if (capture.dual_endstops)
            out.notes.emplace_back(
                "M666 without M665: its dual endstops' adjustments, not a delta's geometry (the "
                "firmware keeps them; the box does not change them)");
        out.notes.emplace_back(
            "not in the capture, left to the defaults: the bed's size (200 x 200 mm), the hole "
            "pitch and margin, the line width and filament");
        return out;
    }
    throw ImportError(
        std::string("the capture holds no delta geometry (M665, G33's report") +
        (capture.dual_endstops ? "; its M666 alone is a cartesian's dual endstops" : "") +
        ") and no steps per mm (M92): capture the printer's whole reply to M503");
}

RrfConfig read_rrf_config(const std::vector<std::string>& files) {
    RrfConfig config;
    for (const auto& file : files)
        for (const auto& raw : lines_of(file)) {
            const std::string line = trimmed(raw.substr(0, raw.find(';')));
            const auto is = [&](std::string_view word) {
                return line.rfind(word, 0) == 0 &&
                       (line.size() == word.size() || line[word.size()] == ' ');
            };
            if (is("M665")) {
                config.m665 = line;
                if (auto b = number_after(line, " B")) config.bed_radius_mm = b;
            } else if (is("M666")) {
                config.m666 = line;
            }
        }
    return config;
}

ImportedMachine import_rrf(const std::vector<std::string>& files, const ImportOptions& options) {
    const RrfConfig config = read_rrf_config(files);
    if (!config.m665)
        throw ImportError(
            "no M665 in the files: give config.g and config-override.g of a delta printer");
    std::vector<std::string> notes;
    std::string m666 = config.m666.value_or("M666 X0 Y0 Z0");
    if (!config.m666)
        notes.emplace_back("no M666 in the files: the endstop adjustments taken as 0");
    DeltaGeometry g;
    try {
        g = geometry_from_settings("rrf", {*config.m665, m666});
    } catch (const std::exception& e) {
        throw ImportError(e.what());
    }
    auto out = delta_machine("rrf", g, config.bed_radius_mm, "M665 B", options);
    out.notes.insert(out.notes.begin(),
                     "the delta geometry from the last M665 and M666 of the files");
    out.notes.insert(out.notes.end(), notes.begin(), notes.end());
    return out;
}

namespace {

using Sections = KlipperSections;

std::string folder_of(const std::string& path) {
    const auto slash = path.rfind('/');
    return slash == std::string::npos ? std::string() : path.substr(0, slash + 1);
}

constexpr int kDeepestInclude = 32;

struct Includes {
    const ReadIncluded& read;
    const ListIncluded& list;
};

void read_klipper_file(const std::string& path, const std::string& text, const Includes& includes,
                       std::vector<std::string>& chain, Sections& sections, Sections& saved,
                       std::vector<std::string>& notes);

// One [include SPEC] of the file at `path`, as Klipper resolves it: SPEC relative to the file's
// folder; a wildcard names every matching file, read in sorted order (none matching is no
// error); a plain name that is not there is noted.
void read_klipper_include(const std::string& path, const std::string& spec,
                          const Includes& includes, std::vector<std::string>& chain,
                          Sections& sections, Sections& saved, std::vector<std::string>& notes) {
    const std::string pattern = folder_of(path) + spec;
    if (spec.find_first_of("*?[") == std::string::npos) {
        if (const auto content = includes.read(pattern)) {
            read_klipper_file(pattern, *content, includes, chain, sections, saved, notes);
        } else {
            notes.push_back(pattern + " (included) is not here: its settings are not read");
        }
        return;
    }
    if (!includes.list) {
        notes.push_back(pattern +
                        " (included, a wildcard) cannot be listed here: its settings are not "
                        "read");
        return;
    }
    std::vector<std::string> paths = includes.list(pattern);
    std::sort(paths.begin(), paths.end());
    for (const auto& included : paths) {
        if (const auto content = includes.read(included)) {
            read_klipper_file(included, *content, includes, chain, sections, saved, notes);
        } else {
            notes.push_back(included + " (included) cannot be read: its settings are not read");
        }
    }
}

// The file's place in the chain of includes; refused where it loops or nests too deep.
void enter_include_chain(std::vector<std::string>& chain, const std::string& path) {
    if (std::find(chain.begin(), chain.end(), path) != chain.end()) {
        std::string loop;
        for (const auto& p : chain) loop += p + " -> ";
        throw ImportError("printer.cfg's includes loop: " + loop + path);
    }
    if (static_cast<int>(chain.size()) >= kDeepestInclude)
        throw ImportError("printer.cfg's includes nest deeper than " +
                          std::to_string(kDeepestInclude) + " files");
    chain.push_back(path);
}

// A line of SAVE_CONFIG's block (#*# ...): a section, or a value saved in it.
void read_saved_line(const std::string& raw, std::string& section, Sections& saved) {
    const std::string line = trimmed(std::string_view(raw).substr(3));
    if (line.size() > 2 && line.front() == '[' && line.back() == ']')
        section = trimmed(line.substr(1, line.size() - 2));
    else if (const auto eq = line.find_first_of("=:"); eq != std::string::npos)
        saved[section][trimmed(line.substr(0, eq))] = trimmed(line.substr(eq + 1));
}

void read_klipper_file(const std::string& path, const std::string& text, const Includes& includes,
                       std::vector<std::string>& chain, Sections& sections, Sections& saved,
                       std::vector<std::string>& notes) {
    enter_include_chain(chain, path);
    std::string section;
    bool in_saved = false;
    for (const auto& raw : lines_of(text)) {
        if (raw.rfind("#*#", 0) == 0) {
            if (raw.find("SAVE_CONFIG") != std::string::npos) {
                in_saved = true;
                continue;
            }
            if (in_saved) read_saved_line(raw, section, saved);
            continue;
        }
        if (!raw.empty() && std::isspace(static_cast<unsigned char>(raw[0]))) continue;
        std::string line = raw.substr(0, raw.find_first_of("#;"));
        line = trimmed(line);
        if (line.empty()) continue;
        if (line.front() == '[' && line.back() == ']') {
            const std::string name = trimmed(line.substr(1, line.size() - 2));
            if (name.rfind("include ", 0) == 0) {
                read_klipper_include(path, trimmed(name.substr(8)), includes, chain, sections,
                                     saved, notes);
                section.clear();
                continue;
            }
            section = name;
            sections[section];  // a section with no options is there too ([skew_correction])
            continue;
        }
        if (const auto sep = line.find_first_of(":="); sep != std::string::npos)
            sections[section][trimmed(line.substr(0, sep))] = trimmed(line.substr(sep + 1));
    }
    chain.pop_back();
}

}  // namespace

KlipperSections read_klipper_sections(const std::string& path, const std::string& text,
                                      const ReadIncluded& read, std::vector<std::string>& notes,
                                      const ListIncluded& list) {
    Sections sections, saved;
    std::vector<std::string> chain;
    read_klipper_file(path, text, Includes{read, list}, chain, sections, saved, notes);
    for (const auto& [name, keys] : saved)
        for (const auto& [key, value] : keys) sections[name][key] = value;
    return sections;
}

KlipperConfig read_klipper_config(const std::string& path, const std::string& text,
                                  const ReadIncluded& read, const ListIncluded& list) {
    KlipperConfig config;
    const Sections sections = read_klipper_sections(path, text, read, config.notes, list);
    const auto value = [&](const std::string& section, const std::string& key) {
        const auto s = sections.find(section);
        if (s == sections.end()) return std::optional<std::string>{};
        const auto k = s->second.find(key);
        return k == s->second.end() ? std::optional<std::string>{} : k->second;
    };
    const auto kinematics = value("printer", "kinematics");
    if (!kinematics) throw ImportError(path + ": no [printer] kinematics");
    if (*kinematics != "delta")
        throw ImportError(path + ": kinematics is '" + *kinematics +
                          "', not delta: calbox imports Klipper deltas");
    const auto number = [&](const std::string& section, const std::string& key,
                            std::optional<double> fallback = std::nullopt) {
        const auto v = value(section, key);
        if (!v) {
            if (fallback) return *fallback;
            throw ImportError(path + ": no " + key + " in [" + section + "]");
        }
        return parse_number(*v, path + ": [" + section + "] " + key);
    };
    config.delta.delta_radius_mm = number("printer", "delta_radius");
    const double arm = number("stepper_a", "arm_length");
    const double endstop = number("stepper_a", "position_endstop");
    const char* steppers[3] = {"stepper_a", "stepper_b", "stepper_c"};
    const double angles[3] = {210, 330, 90};
    for (std::size_t i = 0; i < 3; ++i) {
        config.delta.arm_length_mm[i] = number(steppers[i], "arm_length", arm);
        config.delta.position_endstop_mm[i] = number(steppers[i], "position_endstop", endstop);
        config.delta.angle_deg[i] = number(steppers[i], "angle", angles[i]);
    }
    if (value("printer", "print_radius"))
        config.print_radius_mm = number("printer", "print_radius");
    std::array<double, 3> steps_per_mm{};
    bool steps_given = true;
    for (std::size_t i = 0; i < 3; ++i) {
        // Klipper wants each stepper's own; stepper_a's stand in where a file leaves them out.
        const auto given = [&](const std::string& key) {
            return value(steppers[i], key) ? steppers[i] : std::string("stepper_a");
        };
        const std::string rotation = given("rotation_distance"), microsteps = given("microsteps");
        if (!value(rotation, "rotation_distance") || !value(microsteps, "microsteps")) {
            steps_given = false;
            continue;
        }
        steps_per_mm[i] = number(given("full_steps_per_rotation"), "full_steps_per_rotation", 200) *
                          number(microsteps, "microsteps") / number(rotation, "rotation_distance");
    }
    if (steps_given) config.steps_per_mm = steps_per_mm;
    for (int n = 0;; ++n) {
        const std::string key = "height" + std::to_string(n);
        const auto height = value("delta_calibrate", key);
        const auto at = value("delta_calibrate", key + "_pos");
        if (!height || !at) break;
        KlipperSavedProbe point;
        point.height_mm = number("delta_calibrate", key);
        std::string positions = *at;
        std::replace(positions.begin(), positions.end(), ',', ' ');
        std::istringstream in(positions);
        for (double& steps : point.steps_below_endstop)
            if (!(in >> steps))
                throw ImportError(std::string(path).append(": ").append(key).append(
                    "_pos is not three stepper positions"));
        config.saved_probe.push_back(point);
    }
    return config;
}

ImportedMachine import_klipper(const std::string& path, const std::string& text,
                               const ReadIncluded& read, const ImportOptions& options,
                               const ListIncluded& list) {
    const KlipperConfig config = read_klipper_config(path, text, read, list);
    auto out = delta_machine("klipper", from_klipper(config.delta), config.print_radius_mm,
                             "[printer] print_radius", options);
    out.notes.insert(out.notes.begin(),
                     "the delta geometry from [printer] and [stepper_a/b/c], SAVE_CONFIG's over "
                     "the sections above it");
    out.notes.insert(out.notes.end(), config.notes.begin(), config.notes.end());
    return out;
}

std::string machine_file_text(const ImportedMachine& imported) {
    const MachineFile& m = imported.machine;
    std::ostringstream out;
    out << "# calbox machine file, imported from the printer's own files:\n";
    for (const auto& note : imported.notes) out << "# - " << note << "\n";
    out << "[machine]\nkind = \"" << m.kind << "\"\nfirmware = \"" << m.firmware << "\"\n";
    if (m.delta) {
        const auto& d = *m.delta;
        out << "bed_radius_mm = " << number_toml(m.bed_radius_mm) << "\n[delta]\n"
            << "diagonal_rod_mm = " << number_toml(d.diagonal_rod_mm) << "\n"
            << "diagonal_rod_trim_mm = " << triple_toml(d.diagonal_rod_trim_mm) << "\n"
            << "radius_mm = " << number_toml(d.radius_mm) << "\n"
            << "tower_angle_trim_deg = " << triple_toml(d.tower_angle_trim_deg) << "\n"
            << "endstop_offset_mm = " << triple_toml(d.endstop_offset_mm) << "\n"
            << "height_mm = " << number_toml(d.height_mm) << "\n";
    } else if (m.planar) {
        out << "bed_size_x_mm = " << number_toml(m.bed_size_x_mm) << "\n"
            << "bed_size_y_mm = " << number_toml(m.bed_size_y_mm) << "\n[planar]\n"
            << "holes = \"" << m.planar->holes << "\"\n";
        if (m.planar->steps_per_mm_x)
            out << "steps_per_mm_x = " << number_toml(*m.planar->steps_per_mm_x) << "\n";
        if (m.planar->steps_per_mm_y)
            out << "steps_per_mm_y = " << number_toml(*m.planar->steps_per_mm_y) << "\n";
    }
    return out.str();
}

}  // namespace calbox::models
