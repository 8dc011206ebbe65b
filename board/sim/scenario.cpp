#include "board/sim/scenario.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <set>

namespace calbox::sim {
namespace {

class Reader {
  public:
    Reader(std::string file, const toml::table& table, std::string section)
        : file_(std::move(file)), table_(table), section_(std::move(section)) {}

    [[noreturn]] void fail(const std::string& key, const std::string& why) const {
        throw ScenarioError(file_ + ": " + (section_.empty() ? "" : "[" + section_ + "] ") + key +
                            ": " + why);
    }
    void number(const char* key, double& field, double min, double max) {
        seen_.insert(key);
        const auto* node = table_.get(key);
        if (node == nullptr) return;
        const auto v = node->value<double>();
        if (!v || !std::isfinite(*v)) fail(key, "must be a number");
        if (*v < min || *v > max) {
            fail(key, "must be between " + std::to_string(min) + " and " + std::to_string(max));
        }
        field = *v;
    }
    void integer(const char* key, int& field, int min, int max) {
        double v = field;
        number(key, v, min, max);
        if (v != std::floor(v)) fail(key, "must be a whole number");
        field = static_cast<int>(v);
    }
    void boolean(const char* key, bool& field) {
        seen_.insert(key);
        const auto* node = table_.get(key);
        if (node == nullptr) return;
        const auto v = node->value<bool>();
        if (!v) fail(key, "must be true or false");
        field = *v;
    }
    void text(const char* key, std::string& field, const std::set<std::string>& allowed) {
        seen_.insert(key);
        const auto* node = table_.get(key);
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
    std::vector<double> numbers(const char* key, std::size_t min_count, std::size_t max_count) {
        seen_.insert(key);
        const auto* node = table_.get(key);
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
    void triple(const char* key, std::array<double, 3>& field) {
        const auto v = numbers(key, 3, 3);
        if (!v.empty()) field = {v[0], v[1], v[2]};
    }
    void point(const char* key, Vec3& field) {
        const auto v = numbers(key, 3, 3);
        if (!v.empty()) field = {v[0], v[1], v[2]};
    }
    // Every key must have been read: a typo is an error, not a silent default.
    void finish() const {
        for (const auto& [key, node] : table_) {
            if (seen_.count(std::string(key.str())) == 0 && !node.is_table()) {
                fail(std::string(key.str()), "unknown key");
            }
        }
    }

  private:
    std::string file_;
    const toml::table& table_;
    std::string section_;
    std::set<std::string> seen_;
};

const toml::table* subtable(const std::string& file, const toml::table& t, const char* name) {
    const auto* node = t.get(name);
    if (node == nullptr) return nullptr;
    if (!node->is_table())
        throw ScenarioError(file + ": [" + std::string(name) + "] must be a table");
    return node->as_table();
}

void read_delta(const std::string& file, const toml::table& t, const std::string& section,
                DeltaParams& p) {
    Reader r(file, t, section);
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

}  // namespace

Scenario load_scenario(const std::string& path) {
    toml::table root;
    try {
        root = toml::parse_file(path);
    } catch (const toml::parse_error& e) {
        const auto& where = e.source().begin;
        throw ScenarioError(path + ":" + std::to_string(where.line) + ": " +
                            std::string(e.description()));
    }
    Scenario s;
    s.path = path;
    for (const auto& [key, node] : root) {
        static const std::set<std::string> kSections{"machine", "delta",  "truth",
                                                     "twin",    "camera", "photo"};
        if (kSections.count(std::string(key.str())) == 0) {
            throw ScenarioError(path + ": unknown section or key '" + std::string(key.str()) + "'");
        }
    }
    const auto* machine = subtable(path, root, "machine");
    if (machine == nullptr) throw ScenarioError(path + ": missing [machine]");
    {
        Reader r(path, *machine, "machine");
        auto& m = s.machine;
        r.text("kind", m.kind, {"delta", "cartesian", "router", "laser"});
        r.text("firmware", m.firmware, {"marlin", "rrf", "klipper", "grbl", "linuxcnc"});
        r.number("bed_radius_mm", m.bed_radius_mm, 10, 1000);
        r.number("bed_size_x_mm", m.bed_size_x_mm, 10, 5000);
        r.number("bed_size_y_mm", m.bed_size_y_mm, 10, 5000);
        r.number("line_width_mm", m.line_width_mm, 0.05, 5);
        r.number("layer_height_mm", m.layer_height_mm, 0.01, 5);
        r.number("filament_diameter_mm", m.filament_diameter_mm, 0.5, 5);
        r.number("tool_width_mm", m.tool_width_mm, 0.001, 20);
        // Shared machine-file keys the twin does not model yet are still accepted.
        std::string ignored;
        r.text("bed_material", ignored, {});
        double unused = 0;
        r.number("bed_temperature_c", unused, -50, 200);
        r.number("calibration_temperature_c", unused, -50, 200);
        r.finish();
    }
    if (s.machine.kind == "delta") {
        const auto* delta = subtable(path, root, "delta");
        if (delta == nullptr) throw ScenarioError(path + ": a delta scenario needs [delta]");
        read_delta(path, *delta, "delta", s.delta_firmware);
    }
    s.delta_truth = s.delta_firmware;
    if (const auto* truth = subtable(path, root, "truth")) {
        for (const auto& [key, node] : *truth) {
            if (key.str() != "delta" && key.str() != "cartesian") {
                throw ScenarioError(path + ": [truth] has unknown part '" + std::string(key.str()) +
                                    "'");
            }
        }
        if (const auto* d = subtable(path, *truth, "delta")) {
            if (s.machine.kind != "delta")
                throw ScenarioError(path + ": [truth.delta] on a " + s.machine.kind);
            read_delta(path, *d, "truth.delta", s.delta_truth);
        }
        if (const auto* c = subtable(path, *truth, "cartesian")) {
            Reader r(path, *c, "truth.cartesian");
            r.number("scale_error_x", s.cartesian_truth.scale_error_x, -0.05, 0.05);
            r.number("scale_error_y", s.cartesian_truth.scale_error_y, -0.05, 0.05);
            r.number("squareness_error_deg", s.cartesian_truth.squareness_error_deg, -5, 5);
            r.finish();
        }
    }
    if (const auto* twin = subtable(path, root, "twin")) {
        Reader r(path, *twin, "twin");
        r.boolean("zero_height_at_centre", s.zero_height_at_centre);
        r.number("segment_mm", s.segment_mm, 0.01, 10);
        r.finish();
    }
    if (const auto* camera = subtable(path, root, "camera")) {
        Reader r(path, *camera, "camera");
        ScenarioCamera c;
        std::string model = "pinhole";
        r.text("model", model, {"pinhole", "fisheye"});
        c.intrinsics.model = model == "fisheye" ? LensModel::fisheye : LensModel::pinhole;
        r.integer("width_px", c.intrinsics.width_px, 16, 20000);
        r.integer("height_px", c.intrinsics.height_px, 16, 20000);
        c.intrinsics.cx = (c.intrinsics.width_px - 1) / 2.0;
        c.intrinsics.cy = (c.intrinsics.height_px - 1) / 2.0;
        r.number("fx", c.intrinsics.fx, 1, 1e6);
        c.intrinsics.fy = c.intrinsics.fx;
        r.number("fy", c.intrinsics.fy, 1, 1e6);
        r.number("cx", c.intrinsics.cx, -1e5, 1e5);
        r.number("cy", c.intrinsics.cy, -1e5, 1e5);
        c.intrinsics.distortion = r.numbers("distortion", 0, model == "fisheye" ? 4 : 5);
        r.point("position_mm", c.position_mm);
        r.point("look_at_mm", c.look_at_mm);
        r.number("roll_deg", c.roll_deg, -180, 180);
        r.finish();
        if ((c.position_mm - c.look_at_mm).norm() < 1)
            r.fail("position_mm", "must differ from look_at_mm");
        s.camera = c;
    }
    if (const auto* photo = subtable(path, root, "photo")) {
        Reader r(path, *photo, "photo");
        auto& p = s.photo;
        r.integer("supersample", p.supersample, 1, 16);
        r.number("blur_sigma_px", p.blur_sigma_px, 0, 50);
        r.number("noise_sigma_dn", p.noise_sigma_dn, 0, 100);
        double seed = static_cast<double>(p.seed);
        r.number("seed", seed, 0, 9.0e15);
        p.seed = static_cast<std::uint64_t>(seed);
        r.number("exposure_dn", p.exposure_dn, 1, 1000);
        r.number("lighting_gradient", p.lighting_gradient, -1, 1);
        r.number("lighting_direction_deg", p.lighting_direction_deg, -360, 360);
        r.number("vignetting", p.vignetting, 0, 0.9);
        r.number("bed_albedo", s.bed_albedo, 0, 1);
        r.number("material_albedo", s.material_albedo, 0, 1);
        r.finish();
    }
    return s;
}

std::unique_ptr<MachineTwin> make_machine_twin(const Scenario& s) {
    if (s.machine.kind == "delta") {
        auto twin = std::make_unique<DeltaTwin>(s.delta_truth, s.delta_firmware);
        if (s.zero_height_at_centre) twin->zero_height_at_centre();
        return twin;
    }
    return std::make_unique<CartesianTwin>(s.cartesian_truth);
}

ToolSettings tool_settings_of(const Scenario& s) {
    ToolSettings t;
    t.kind = s.machine.kind == "laser"    ? ToolKind::laser
             : s.machine.kind == "router" ? ToolKind::spindle
                                          : ToolKind::extruder;
    t.filament_diameter_mm = s.machine.filament_diameter_mm;
    t.layer_height_mm = s.machine.layer_height_mm;
    t.tool_width_mm = s.machine.tool_width_mm;
    t.segment_mm = s.segment_mm;
    return t;
}

}  // namespace calbox::sim
