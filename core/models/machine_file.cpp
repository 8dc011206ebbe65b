#include "core/models/machine_file.hpp"

#include <cstdint>
#include <cstdio>

#include "core/models/link_kinds.hpp"
#include "core/models/toml_reader.hpp"

namespace calbox::models {

const toml::node* TomlReader::find(const char* key) {
    seen_.insert(key);
    return table_.get(key);
}

void TomlReader::number(const char* key, double& field, double min, double max) {
    const auto* node = find(key);
    if (node == nullptr) return;
    const auto v = node->value<double>();
    if (!v || !std::isfinite(*v)) fail(key, "must be a number");
    if (*v < min || *v > max)
        fail(key, "must be between " + std::to_string(min) + " and " + std::to_string(max));
    field = *v;
}

void TomlReader::number(const char* key, std::optional<double>& field, double min, double max) {
    if (table_.get(key) == nullptr) {
        seen_.insert(key);
        return;
    }
    double v = 0;
    number(key, v, min, max);
    field = v;
}

void TomlReader::integer(const char* key, int& field, int min, int max) {
    double v = field;
    number(key, v, min, max);
    if (v != std::floor(v)) fail(key, "must be a whole number");
    field = static_cast<int>(v);
}

void TomlReader::boolean(const char* key, bool& field) {
    const auto* node = find(key);
    if (node == nullptr) return;
    const auto v = node->value<bool>();
    if (!v) fail(key, "must be true or false");
    field = *v;
}

void TomlReader::text(const char* key, std::string& field, const std::set<std::string>& allowed) {
    const auto* node = find(key);
    if (node == nullptr) return;
    const auto v = node->value<std::string>();
    if (!v) fail(key, "must be a string");
    if (!allowed.empty() && allowed.count(*v) == 0) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(key, "'" + *v + "' is not one of " + list);
    }
    field = *v;
}

void TomlReader::text(const char* key, std::optional<std::string>& field) {
    if (table_.get(key) == nullptr) {
        seen_.insert(key);
        return;
    }
    std::string v;
    text(key, v, {});
    field = v;
}

std::vector<double> TomlReader::numbers(const char* key, std::size_t min_count,
                                        std::size_t max_count) {
    const auto* node = find(key);
    if (node == nullptr) return {};
    const auto* array = node->as_array();
    if (array == nullptr) fail(key, "must be an array of numbers");
    std::vector<double> out;
    for (const auto& element : *array) {
        const auto v = element.value<double>();
        if (!v || !std::isfinite(*v)) fail(key, "must be an array of numbers");
        out.push_back(*v);
    }
    if (out.size() < min_count || out.size() > max_count) {
        fail(key, "needs " + std::to_string(min_count) +
                      (max_count != min_count ? " to " + std::to_string(max_count) : "") +
                      " numbers");
    }
    return out;
}

void TomlReader::triple(const char* key, std::array<double, 3>& field) {
    const auto v = numbers(key, 3, 3);
    if (!v.empty()) field = {v[0], v[1], v[2]};
}

void TomlReader::finish() const {
    for (const auto& [key, node] : table_) {
        if (seen_.count(std::string(key.str())) == 0 && !node.is_table())
            fail(std::string(key.str()), "unknown key");
    }
}

const toml::table* subtable(const std::string& file, const toml::table& parent, const char* name) {
    const auto* node = parent.get(name);
    if (node == nullptr) return nullptr;
    if (!node->is_table())
        throw MachineFileError(file + ": [" + std::string(name) + "] must be a table");
    return node->as_table();
}

toml::table parse_toml(std::string_view text, const std::string& source) {
    try {
        return toml::parse(text, source);
    } catch (const toml::parse_error& e) {
        throw MachineFileError(source + ":" + std::to_string(e.source().begin.line) + ": " +
                               std::string(e.description()));
    }
}

void read_delta_settings(const std::string& file, const toml::table& t, const std::string& section,
                         DeltaSettings& p) {
    TomlReader r(file, t, section);
    r.number("diagonal_rod_mm", p.diagonal_rod_mm, 50, 2000);
    r.triple("diagonal_rod_trim_mm", p.diagonal_rod_trim_mm);
    r.number("radius_mm", p.radius_mm, 20, 1000);
    r.triple("tower_angle_trim_deg", p.tower_angle_trim_deg);
    r.triple("endstop_offset_mm", p.endstop_offset_mm);
    r.number("height_mm", p.height_mm, 10, 3000);
    r.finish();
    for (double a : p.tower_angle_trim_deg)
        if (std::abs(a) > 10)
            r.fail("tower_angle_trim_deg", "trims beyond 10 degrees are not a delta");
    for (double e : p.endstop_offset_mm)
        if (e > 0 || e < -20)
            r.fail("endstop_offset_mm", "offsets must lie in [-20, 0] (Marlin's M666)");
    for (double d : p.diagonal_rod_trim_mm)
        if (std::abs(d) > 20)
            r.fail("diagonal_rod_trim_mm", "trims beyond 20 mm are not plausible");
    if (!(p.diagonal_rod_mm > p.radius_mm)) r.fail("diagonal_rod_mm", "must exceed radius_mm");
}

namespace {

void refuse_unknown_sections(const std::string& file, const toml::table& root,
                             std::initializer_list<std::string_view> other_sections) {
    for (const auto& [key, node] : root) {
        const std::string_view name = key.str();
        bool known = name == "machine" || name == "delta" || name == "galvo" || name == "planar" ||
                     name == "probe" || name == "touch_probe" || name == "limits" || name == "link";
        for (const auto& s : other_sections) known = known || s == name;
        if (!known)
            throw MachineFileError(file + ": unknown section or key '" + std::string(name) + "'");
    }
}

// [machine]: the kind, the firmware, the work area, the tool's and the bed's settings.
void read_machine_section(const std::string& file, const toml::table& machine, MachineFile& m) {
    TomlReader r(file, machine, "machine");
    r.text("kind", m.kind, machine_kind_names());
    r.text("firmware", m.firmware, {"marlin", "rrf", "klipper", "grbl", "linuxcnc"});
    r.number("bed_radius_mm", m.bed_radius_mm, 10, 1000);
    r.number("bed_size_x_mm", m.bed_size_x_mm, 10, 5000);
    r.number("bed_size_y_mm", m.bed_size_y_mm, 10, 5000);
    r.number("travel_min_x_mm", m.travel_min_x_mm, -10000, 10000);
    r.number("travel_max_x_mm", m.travel_max_x_mm, -10000, 10000);
    r.number("travel_min_y_mm", m.travel_min_y_mm, -10000, 10000);
    r.number("travel_max_y_mm", m.travel_max_y_mm, -10000, 10000);
    r.number("work_zero_x_mm", m.work_zero_x_mm, -10000, 10000);
    r.number("work_zero_y_mm", m.work_zero_y_mm, -10000, 10000);
    r.number("line_width_mm", m.line_width_mm, 0.05, 5);
    r.number("layer_height_mm", m.layer_height_mm, 0.01, 5);
    r.number("filament_diameter_mm", m.filament_diameter_mm, 0.5, 5);
    r.number("tool_width_mm", m.tool_width_mm, 0.001, 20);
    r.number("feed_mm_s", m.feed_mm_s, 0.1, 2000);
    r.number("travel_feed_mm_s", m.travel_feed_mm_s, 0.1, 5000);
    r.number("laser_power", m.laser_power, 0.0, 1.0);
    r.number("spindle_rpm", m.spindle_rpm, 0, 100000);
    r.number("cut_depth_mm", m.cut_depth_mm, 0.01, 50);
    r.number("safe_height_mm", m.safe_height_mm, 0.1, 200);
    {
        std::string material;
        r.text("bed_material", material, {"aluminium", "glass", "steel", "fr4"});
        if (!material.empty()) m.bed_material = material;
    }
    r.number("bed_temperature_c", m.bed_temperature_c, -50, 200);
    r.number("nozzle_temperature_c", m.nozzle_temperature_c, 0, 500);
    r.number("photo_bed_temperature_c", m.photo_bed_temperature_c, -50, 200);
    r.text("start_gcode", m.start_gcode);
    r.text("end_gcode", m.end_gcode);
    r.finish();
    {
        const auto t = planar_travel_mm(m);
        if (!(t[2] > t[0]) || !(t[3] > t[1]))
            throw MachineFileError(file +
                                   ": [machine] travel_max_x_mm and travel_max_y_mm must "
                                   "exceed travel_min_x_mm and travel_min_y_mm");
    }
    if (m.photo_bed_temperature_c && (!m.bed_material || !m.bed_temperature_c)) {
        throw MachineFileError(file +
                               ": [machine] photo_bed_temperature_c needs bed_material and "
                               "bed_temperature_c");
    }
}

// [link]: how the box reaches the machine; a host's keys only on a host's kind.
void read_link_section(const std::string& file, const toml::table& link, MachineFile& m) {
    TomlReader l(file, link, "link");
    l.text("kind", m.link.kind, link_kind_names());
    std::optional<std::string> url, key_file, ca_file;
    std::optional<double> reply_timeout_s, restart_timeout_s;
    l.text("url", url);
    l.text("key_file", key_file);
    l.text("ca_file", ca_file);
    l.number("reply_timeout_s", reply_timeout_s, 0.1, 3600);
    l.number("restart_timeout_s", restart_timeout_s, 1, 3600);
    l.finish();
    // A serial link's timing is the box's own (its G-code host); these keys are a host's.
    if (!m.link.is_host()) {
        const std::string why = "is a host's (kind = " + link_kind_list(" | ", true) + ")";
        if (url) l.fail("url", why);
        if (key_file) l.fail("key_file", why);
        if (ca_file) l.fail("ca_file", why);
        if (reply_timeout_s || restart_timeout_s)
            l.fail(reply_timeout_s ? "reply_timeout_s" : "restart_timeout_s", why);
    }
    m.link.url = url.value_or("");
    m.link.key_file = key_file.value_or("");
    m.link.ca_file = ca_file.value_or("");
    m.link.reply_timeout_s = reply_timeout_s.value_or(m.link.reply_timeout_s);
    m.link.restart_timeout_s = restart_timeout_s.value_or(m.link.restart_timeout_s);
    if (const auto why = link_mismatch(m); !why.empty()) l.fail("kind", why);
}

// [probe]: a delta printer's own probe, read over the link.
void read_probe_section(const std::string& file, const toml::table& probe, MachineFile& m) {
    if (!m.is_delta()) throw MachineFileError(file + ": [probe] on a " + m.kind + " machine");
    // Klipper's PROBE report needs the probe's z_offset, in printer.cfg: read through
    // Moonraker's settings in force.
    if (m.firmware == "klipper" && m.link.kind != "moonraker")
        throw MachineFileError(file +
                               ": [probe] on Klipper is read through Moonraker ([link] kind = "
                               "\"moonraker\"), which gives the probe's z_offset; else give "
                               "its heights to `calbox solve delta --probe`");
    if (m.firmware != "marlin" && m.firmware != "rrf" && m.firmware != "klipper")
        throw MachineFileError(file +
                               ": [probe] is read over the link from Marlin, "
                               "RepRapFirmware or Klipper, not " +
                               m.firmware);
    m.probe.emplace();
    TomlReader p(file, probe, "probe");
    p.number("radius_mm", m.probe->radius_mm, 1, 1000);
    p.number("repeatability_mm", m.probe->repeatability_mm, 0.0005, 1);
    p.finish();
    if (!(m.probe->radius_mm > 0)) p.fail("radius_mm", "is required");
    if (m.probe->radius_mm > m.bed_radius_mm)
        p.fail("radius_mm", "probes beyond the bed's radius (bed_radius_mm)");
}

// [touch_probe]: a router's on grbl (G38.2).
void read_touch_probe_section(const std::string& file, const toml::table& touch, MachineFile& m) {
    if (m.kind != "router" || m.firmware != "grbl")
        throw MachineFileError(file + ": [touch_probe] is a router's on grbl (G38.2), not a " +
                               m.kind + "'s on " + m.firmware);
    auto& t = m.touch_probe.emplace();
    TomlReader p(file, touch, "touch_probe");
    std::optional<double> clear_z;
    p.number("clear_z_mm", clear_z, -2000, 2000);
    p.number("travel_mm", t.travel_mm, 1, 200);
    p.number("feed_mm_min", t.feed_mm_min, 1, 1000);
    p.number("repeatability_mm", t.repeatability_mm, 0.0005, 1);
    p.finish();
    if (!clear_z)
        p.fail("clear_z_mm",
               "is required: the machine Z the tool is lifted to before it moves over the bed");
    t.clear_z_mm = *clear_z;
}

// [limits]: the bounds a delta's correction must pass before it is sent.
void read_limits_section(const std::string& file, const toml::table& limits, MachineFile& m) {
    if (!m.is_delta()) throw MachineFileError(file + ": [limits] on a " + m.kind + " machine");
    TomlReader l(file, limits, "limits");
    auto& d = m.delta_limits;
    l.number("max_rod_change_fraction", d.max_rod_change_fraction, 0.0001, 0.2);
    l.number("max_angle_trim_deg", d.max_angle_trim_deg, 0.01, 10);
    l.number("max_radius_change_fraction", d.max_radius_change_fraction, 0.0001, 0.2);
    l.number("max_residual_ratio", d.max_residual_ratio, 1, 100);
    l.finish();
}

// [galvo] or [planar], the family's own (its defaults where left out); another's is refused.
void read_galvo_or_planar_section(const std::string& file, const toml::table& root,
                                  MachineFile& m) {
    const auto* galvo = subtable(file, root, "galvo");
    if (m.is_galvo()) {
        m.galvo.emplace();
        if (galvo != nullptr) {
            TomlReader g(file, *galvo, "galvo");
            g.number("field_size_mm", m.galvo->field_size_mm, 5, 2000);
            g.number("substrate_height_mm", m.galvo->substrate_height_mm, -50, 200);
            g.text("marks", m.galvo->marks, {"dark", "light"});
            g.finish();
        }
    } else if (galvo != nullptr) {
        throw MachineFileError(file + ": [galvo] on a " + m.kind + " machine");
    }
    const auto* planar = subtable(file, root, "planar");
    if (m.is_planar()) {
        m.planar.emplace();
        m.planar->holes = m.kind_row().planar_holes;
        if (planar != nullptr) {
            TomlReader g(file, *planar, "planar");
            g.number("hole_pitch_mm", m.planar->hole_pitch_mm, 2, 500);
            g.number("margin_mm", m.planar->margin_mm, 0, 500);
            g.number("surface_height_mm", m.planar->surface_height_mm, -50, 300);
            g.number("tool_length_mm", m.planar->tool_length_mm, 0, 1000);
            g.number("plunge_feed_mm_s", m.planar->plunge_feed_mm_s, 0.1, 100);
            g.number("dwell_s", m.planar->dwell_s, 0, 60);
            g.number("steps_per_mm_x", m.planar->steps_per_mm_x, 0.01, 1e6);
            g.number("steps_per_mm_y", m.planar->steps_per_mm_y, 0.01, 1e6);
            g.text("holes", m.planar->holes, {"dark", "light"});
            g.finish();
        }
    } else if (planar != nullptr) {
        throw MachineFileError(file + ": [planar] on a " + m.kind + " machine");
    }
}

}  // namespace

MachineFile read_machine_tables(const std::string& file, const toml::table& root,
                                std::initializer_list<std::string_view> other_sections) {
    refuse_unknown_sections(file, root, other_sections);
    const auto* machine = subtable(file, root, "machine");
    if (machine == nullptr) throw MachineFileError(file + ": missing [machine]");
    MachineFile m;
    read_machine_section(file, *machine, m);
    const auto* delta = subtable(file, root, "delta");
    if (m.is_delta()) {
        if (delta == nullptr) throw MachineFileError(file + ": a delta machine needs [delta]");
        m.delta.emplace();
        read_delta_settings(file, *delta, "delta", *m.delta);
    } else if (delta != nullptr) {
        throw MachineFileError(file + ": [delta] on a " + m.kind + " machine");
    }
    if (const auto* link = subtable(file, root, "link")) read_link_section(file, *link, m);
    if (const auto* probe = subtable(file, root, "probe")) read_probe_section(file, *probe, m);
    if (const auto* touch = subtable(file, root, "touch_probe"))
        read_touch_probe_section(file, *touch, m);
    if (const auto* limits = subtable(file, root, "limits")) read_limits_section(file, *limits, m);
    read_galvo_or_planar_section(file, root, m);
    return m;
}

double bed_expansion_per_k(const std::string& material) {
    // Linear expansion near room temperature (handbook values): the aluminium plate most deltas
    // have, borosilicate glass, the spring-steel sheet, a PCB heater used as the bed.
    if (material == "aluminium") return 23.1e-6;
    if (material == "glass") return 3.3e-6;
    if (material == "steel") return 12.0e-6;
    if (material == "fr4") return 14.0e-6;
    throw MachineFileError("unknown bed material '" + material + "'");
}

double bed_scale_at_photo(const MachineFile& m, std::optional<double> photo_bed_temperature_c) {
    if (!photo_bed_temperature_c) photo_bed_temperature_c = m.photo_bed_temperature_c;
    if (!photo_bed_temperature_c) return 1.0;
    if (!m.bed_material || !m.bed_temperature_c) {
        throw MachineFileError(
            "a photo bed temperature needs bed_material and bed_temperature_c in [machine]");
    }
    return 1.0 +
           bed_expansion_per_k(*m.bed_material) * (*photo_bed_temperature_c - *m.bed_temperature_c);
}

const MachineKind& MachineFile::kind_row() const {
    if (const MachineKind* k = machine_kind(kind)) return *k;
    throw std::invalid_argument("a machine of kind '" + kind + "': calbox knows " +
                                machine_kind_list(", "));
}

bool MachineLinkSettings::is_host() const {
    const LinkKind* k = link_kind(kind);
    return k == nullptr || k->host;
}

std::string link_mismatch(const MachineFile& m) {
    const LinkKind* kind = link_kind(m.link.kind);
    if (kind == nullptr || kind->firmware.empty() || kind->firmware == m.firmware) return {};
    std::string why(kind->serves);
    why += " ([machine] firmware = \"";
    why += kind->firmware;
    why += "\", not \"";
    why += m.firmware;
    why += "\")";
    return why;
}

std::array<double, 4> planar_travel_mm(const MachineFile& m) {
    return {m.travel_min_x_mm.value_or(0), m.travel_min_y_mm.value_or(0),
            m.travel_max_x_mm.value_or(m.bed_size_x_mm),
            m.travel_max_y_mm.value_or(m.bed_size_y_mm)};
}

std::string fingerprint(const MachineFile& m) {
    std::string canonical = m.kind + "|" + m.firmware;
    const auto add = [&](double v) {
        char b[40];
        std::snprintf(b, sizeof b, "|%.6f", v);
        canonical += b;
    };
    for (double v : {m.bed_radius_mm, m.bed_size_x_mm, m.bed_size_y_mm, m.line_width_mm,
                     m.layer_height_mm, m.filament_diameter_mm, m.tool_width_mm})
        add(v);
    if (m.delta) {
        const auto& d = *m.delta;
        add(d.diagonal_rod_mm);
        add(d.radius_mm);
        add(d.height_mm);
        for (const auto* a :
             {&d.diagonal_rod_trim_mm, &d.tower_angle_trim_deg, &d.endstop_offset_mm})
            for (double v : *a) add(v);
    }
    if (m.galvo) {
        add(m.galvo->field_size_mm);
        add(m.galvo->substrate_height_mm);
    }
    if (m.planar) {
        add(m.planar->hole_pitch_mm);
        add(m.planar->margin_mm);
        add(m.planar->surface_height_mm);
        add(m.cut_depth_mm);
    }
    return digest(canonical);
}

std::string digest(std::string_view canonical) {
    std::uint64_t hash = 1469598103934665603ull;  // FNV-1a, 64 bits
    for (const unsigned char c : canonical) {
        hash ^= c;
        hash *= 1099511628211ull;
    }
    char out[32];
    std::snprintf(out, sizeof out, "fnv1a64:%016llx", static_cast<unsigned long long>(hash));
    return out;
}

MachineFile parse_machine_file(std::string_view toml_text, const std::string& source,
                               std::initializer_list<std::string_view> other_sections) {
    const toml::table root = parse_toml(toml_text, source);
    return read_machine_tables(source, root, other_sections);
}

}  // namespace calbox::models
