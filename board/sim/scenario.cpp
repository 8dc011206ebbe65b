#include "board/sim/scenario.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <sstream>

#include "board/sim/truth_table.hpp"
#include "board/sim/twin_kind.hpp"
#include "core/models/toml_reader.hpp"

namespace calbox::sim {
namespace {

// The twin's own reading of a print-and-cut job: the X Y of every G0 and G1 line in order.
std::vector<Vec2> printed_line_of(std::istream& job) {
    std::vector<Vec2> found;
    for (std::string line; std::getline(job, line);) {
        int g = 0;
        double x = 0, y = 0;
        if (std::sscanf(line.c_str(), "G%d X%lf Y%lf", &g, &x, &y) == 3 && (g == 0 || g == 1))
            found.push_back({x, y});
    }
    return found;
}

using models::TomlReader;

Scenario read_scenario(const std::string& path, const toml::table& root) {
    Scenario s;
    s.path = path;
    s.machine = models::read_machine_tables(
        path, root, {"truth", "twin", "camera", "photo", "faults", "setup", "placement"});
    if (s.machine.delta) s.delta_firmware = twin_params(*s.machine.delta);
    s.delta_truth = s.delta_firmware;
    // The machine's hidden truth: its kind reads its own [truth.*] table and refuses another's.
    const TwinKind& kind = twin_kind_of(s.machine);
    const toml::table* own = nullptr;
    if (const auto* truth = models::subtable(path, root, "truth")) {
        for (const auto& [key, node] : *truth) {
            const std::string part(key.str());
            if (!truth_table_names().contains(part))
                throw ScenarioError(std::string(path)
                                        .append(": [truth] has unknown part '")
                                        .append(part)
                                        .append("'"));
            if (part == kind.truth_table()) {
                own = models::subtable(path, *truth, part.c_str());
            } else if (part == "cartesian" && std::string(kind.truth_table()) == "router") {
                throw ScenarioError(path +
                                    ": a router's truth is [truth.router], not "
                                    "[truth.cartesian]");
            } else {
                throw ScenarioError(std::string(path)
                                        .append(": [truth.")
                                        .append(part)
                                        .append("] on a ")
                                        .append(s.machine.kind));
            }
        }
    }
    if (own != nullptr) {
        const TruthTable table{*own};
        kind.read_truth(path, &table, s);
    } else {
        kind.read_truth(path, nullptr, s);
    }
    if (const auto* twin = models::subtable(path, root, "twin")) {
        TomlReader r(path, *twin, "twin");
        r.boolean("zero_height_at_centre", s.zero_height_at_centre);
        r.text("levelled_by", s.levelled_by, {"centre", "paper", "probe"});
        r.number("segment_mm", s.segment_mm, 0.01, 10);
        r.number("host_print_seconds", s.host_print_seconds, 0, 3600);
        r.boolean("duet_sbc", s.duet_sbc);
        r.boolean("host_tls", s.host_tls);
        std::string first_layer = s.real_first_layer ? "real" : "as_commanded";
        r.text("first_layer", first_layer, {"real", "as_commanded"});
        s.real_first_layer = first_layer == "real";
        r.finish();
    }
    if (const auto* camera = models::subtable(path, root, "camera")) {
        TomlReader r(path, *camera, "camera");
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
        const auto point = [&](const char* key, Vec3& field) {
            const auto v = r.numbers(key, 3, 3);
            if (!v.empty()) field = {v[0], v[1], v[2]};
        };
        point("position_mm", c.position_mm);
        point("look_at_mm", c.look_at_mm);
        r.number("roll_deg", c.roll_deg, -180, 180);
        r.finish();
        if ((c.position_mm - c.look_at_mm).norm() < 1)
            r.fail("position_mm", "must differ from look_at_mm");
        s.camera = c;
    }
    if (const auto* photo = models::subtable(path, root, "photo")) {
        TomlReader r(path, *photo, "photo");
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
        r.number("motion_blur_px", p.motion_blur_px, 0, 50);
        r.number("motion_blur_direction_deg", p.motion_blur_direction_deg, -360, 360);
        r.integer("jpeg_quality", p.jpeg_quality, 0, 100);
        r.number("field_curvature_px", p.field_curvature_px, 0, 20);
        r.number("exposure_us", s.nominal_exposure_us, 10, 1e7);
        for (const auto& [key, field] : {std::pair{"board_surface", &s.board_surface},
                                         std::pair{"bed_surface", &s.bed_surface}}) {
            std::optional<std::string> surface;
            r.text(key, surface);
            if (!surface) continue;
            try {
                glare_of_surface(*surface);
            } catch (const std::invalid_argument& e) {
                r.fail(key, e.what());
            }
            *field = *surface;
        }
        r.number("glare_strength", s.glare_strength, 0, 10);
        if (const auto lamp = r.numbers("lamp_from_camera_mm", 3, 3); !lamp.empty())
            s.lamp_from_camera_mm = {lamp[0], lamp[1], lamp[2]};
        auto& look = s.surface;
        r.number("bed_texture", look.bed_texture, 0, 1);
        r.number("bed_texture_grain_mm", look.bed_texture_grain_mm, 0.01, 100);
        r.number("gloss", look.gloss, 0, 2);
        r.number("light_azimuth_deg", look.light_azimuth_deg, -360, 360);
        r.number("light_elevation_deg", look.light_elevation_deg, 1, 90);
        r.number("bed_temperature_c", s.photo_bed_temperature_c, -50, 200);
        r.number("bed_albedo", s.bed_albedo, 0, 1);
        r.number("material_albedo", s.material_albedo, 0, 1);
        r.finish();
    }
    if (const auto* placement = models::subtable(path, root, "placement")) {
        // A printed card (print and cut) is told by its marks; otherwise a sheet's corner.
        const bool card = placement->contains("marks_mm");
        // The judges are the router's for a sheet and the laser's for a card: no other pairing
        // is judged, so none is taken.
        if (!s.machine.planar || s.machine.kind != (card ? "laser" : "router"))
            throw ScenarioError(path +
                                ": [placement] places a router's job on a sheet (sheet_*) or a "
                                "laser's cut on a printed card (marks_mm); this is a " +
                                s.machine.kind + (card ? " with a card" : " with a sheet"));
        TomlReader r(path, *placement, "placement");
        ScenarioPlacement p;
        r.boolean("on_bed_at_start", p.on_bed_at_start);
        if (card) {
            PrintedCard c;
            r.number("print_origin_x_mm", c.origin_mm.x, -10000, 10000);
            r.number("print_origin_y_mm", c.origin_mm.y, -10000, 10000);
            r.number("print_angle_deg", c.angle_deg, -45, 45);
            r.number("print_stretch", c.stretch_x, 0.95, 1.05);
            c.stretch_y = c.stretch_x;
            r.number("print_stretch_y", c.stretch_y, 0.95, 1.05);
            const auto marks = r.numbers("marks_mm", 6, 8);
            if (marks.size() % 2 != 0) r.fail("marks_mm", "x, y pairs: three or four marks");
            for (std::size_t k = 0; k + 1 < marks.size(); k += 2)
                c.marks_mm.push_back({marks[k], marks[k + 1]});
            r.number("mark_diameter_mm", c.mark_diameter_mm, 1, 50);
            r.number("card_albedo", c.card_albedo, 0, 1);
            r.number("ink_albedo", c.ink_albedo, 0, 1);
            if (c.ink_albedo >= c.card_albedo)
                r.fail("ink_albedo", "the ink must be darker than the card");
            p.card = c;
            p.thickness_mm = 0.3;
        } else {
            r.number("sheet_corner_x_mm", p.sheet.corner_mm.x, -10000, 10000);
            r.number("sheet_corner_y_mm", p.sheet.corner_mm.y, -10000, 10000);
            r.number("sheet_width_mm", p.sheet.width_mm, 10, 10000);
            r.number("sheet_depth_mm", p.sheet.depth_mm, 10, 10000);
            r.number("sheet_angle_deg", p.sheet.angle_deg, -45, 45);
            r.number("sheet_albedo", p.sheet.sheet_albedo, 0, 1);
            r.number("bed_albedo", p.sheet.bed_albedo, 0, 1);
            r.text("corner", p.corner,
                   {"nearest", "front-left", "front-right", "back-right", "back-left"});
        }
        r.number("thickness_mm", p.thickness_mm, 0, 200);
        r.number("goal_mm", p.goal_mm, 0.001, 10);
        std::optional<std::string> job;
        r.text("job", job);
        r.finish();
        if (!job || job->empty())
            throw ScenarioError(path + (card ? ": [placement] job: the cut, in the drawing's frame"
                                             : ": [placement] job: the drilling job placed on "
                                               "the sheet"));
        p.job_path = *job;
        if (p.card) {
            const auto job_file = std::filesystem::path(path).parent_path() / p.job_path;
            std::ifstream in(job_file);
            if (!in)
                throw ScenarioError(path + ": [placement] job: cannot read " + job_file.string());
            p.card->line_mm = printed_line_of(in);
            if (p.card->line_mm.size() < 2)
                throw ScenarioError(path + ": [placement] job: " + job_file.string() +
                                    " cuts no line (G0/G1 X Y)");
        }
        s.placement = p;
    }
    if (const auto* faults = models::subtable(path, root, "faults")) {
        TomlReader r(path, *faults, "faults");
        auto& f = s.faults;
        r.integer("silent_after_lines", f.silent_after_lines, 0, 100000000);
        r.integer("error_at_line", f.error_at_line, 0, 100000000);
        r.number("line_noise", f.line_noise, 0, 0.9);
        r.integer("reset_at_line", f.reset_at_line, 0, 100000000);
        r.integer("camera_fails_at_capture", f.camera_fails_at_capture, 0, 1000000);
        r.integer("camera_hangs_at_capture", f.camera_hangs_at_capture, 0, 1000000);
        r.number("camera_hang_s", f.camera_hang_s, 0, 600);
        r.boolean("settings_ignored", f.settings_ignored);
        auto& h = f.host;
        r.boolean("host_wrong_key", h.wrong_key);
        r.boolean("host_printer_not_ready", h.printer_not_ready);
        r.boolean("host_print_cancelled", h.print_cancelled);
        r.boolean("host_upload_refused", h.upload_refused);
        r.boolean("host_print_never_starts", h.print_never_starts);
        r.integer("host_restart_at_request", h.restart_at_request, 0, 1000000);
        r.integer("host_silent_at_request", h.silent_at_request, 0, 1000000);
        r.boolean("host_config_edited", h.config_edited);
        r.boolean("host_new_config_rejected", h.new_config_rejected);
        std::optional<std::string> restart_at_command;
        r.text("host_restart_at_command", restart_at_command);
        h.restart_at_command = restart_at_command.value_or("");
        r.finish();
        if (!h.restart_at_command.empty() && s.machine.link.kind != "duet" &&
            s.machine.link.kind != "moonraker")
            throw ScenarioError(path +
                                ": [faults] host_restart_at_command is a Duet's or Moonraker's "
                                "(a G-code line or script of its own "
                                "request there): the machine's [link] is " +
                                s.machine.link.kind);
        if (h.any() && !s.machine.link.is_host())
            throw ScenarioError(path + ": [faults] host_* are a host's: the machine's [link] is " +
                                s.machine.link.kind);
    }
    if (const auto* setup = models::subtable(path, root, "setup")) {
        TomlReader r(path, *setup, "setup");
        r.text("calibration_pattern", s.setup.calibration_pattern, {});
        r.text("plane_pattern", s.setup.plane_pattern, {});
        const auto at = r.numbers("plane_board_at_mm", 2, 2);
        if (!at.empty()) s.setup.plane_board_at_mm = {at[0], at[1]};
        std::string surroundings = "grey";
        r.text("board_surroundings", surroundings, {"grey", "dark", "bright", "cluttered"});
        s.setup.board_surroundings = surroundings == "dark"        ? Surroundings::dark
                                     : surroundings == "bright"    ? Surroundings::bright
                                     : surroundings == "cluttered" ? Surroundings::cluttered
                                                                   : Surroundings::grey;
        r.boolean("reference_marks", s.setup.reference_marks);
        const auto marks = r.numbers("reference_marks_at_mm", 0, 32);
        if (marks.size() % 2 != 0) r.fail("reference_marks_at_mm", "x, y pairs");
        for (std::size_t k = 0; k + 1 < marks.size(); k += 2)
            s.setup.reference_marks_at_mm.push_back({marks[k], marks[k + 1]});
        r.number("reference_mark_mm", s.setup.reference_mark_mm, 3, 100);
        r.text("reference_dictionary", s.setup.reference_dictionary, {});
        r.finish();
        try {
            (void)geometry::aruco_dictionary_id(s.setup.reference_dictionary);
        } catch (const geometry::PatternError& e) {
            r.fail("reference_dictionary", e.what());
        }
        const auto chessboard = [&r](const char* key, const std::string& spec) {
            try {
                if (geometry::parse_pattern_spec(spec).kind !=
                    geometry::PatternSpec::Kind::chessboard)
                    r.fail(key, "the sim board's person holds chessboards");
            } catch (const geometry::PatternError& e) {
                r.fail(key, e.what());
            }
        };
        chessboard("calibration_pattern", s.setup.calibration_pattern);
        chessboard("plane_pattern", s.setup.plane_pattern);
    }
    bed_growth_at_photo(s);  // a photo temperature the bed cannot be judged at is refused now
    return s;
}

}  // namespace

PhotoSettings photo_settings_of(const Scenario& s, InView what) {
    PhotoSettings photo = s.photo;
    photo.glare = glare_of_surface(what == InView::board ? s.board_surface : s.bed_surface);
    photo.glare.peak *= s.glare_strength;
    photo.glare.lamp_from_camera_mm = s.lamp_from_camera_mm;
    return photo;
}

double stroke_footprint_mm(const Scenario& s) {
    if (!s.camera) return 1.0;
    return stroke_footprint_mm(s.camera->intrinsics,
                               (s.camera->position_mm - s.camera->look_at_mm).norm());
}

double bed_growth_at_photo(const Scenario& s) {
    if (!s.photo_bed_temperature_c) return 1.0;
    const auto& m = s.machine;
    if (!m.bed_material || !m.bed_temperature_c) {
        throw ScenarioError(s.path +
                            ": [photo] bed_temperature_c needs the bed's material and print "
                            "temperature in [machine]");
    }
    // The twin's own handbook values, kept apart from the code it judges.
    const std::map<std::string, double> per_k{
        {"aluminium", 23.1e-6}, {"glass", 3.3e-6}, {"steel", 12.0e-6}, {"fr4", 14.0e-6}};
    const auto it = per_k.find(*m.bed_material);
    if (it == per_k.end()) throw ScenarioError(s.path + ": no expansion for " + *m.bed_material);
    return 1.0 + it->second * (*s.photo_bed_temperature_c - *m.bed_temperature_c);
}

std::vector<StrokeSegment> carried_by_bed(std::vector<StrokeSegment> strokes, double growth) {
    for (auto& s : strokes) {
        s.a_mm.x *= growth, s.a_mm.y *= growth;
        s.b_mm.x *= growth, s.b_mm.y *= growth;
        s.width_mm *= growth;
    }
    return strokes;
}

std::vector<StrokeSegment> as_photographed(const Scenario& s, std::vector<StrokeSegment> strokes) {
    return twin_kind_of(s.machine).on_the_bed(
        s, carried_by_bed(std::move(strokes), bed_growth_at_photo(s)));
}

DeltaParams twin_params(const models::DeltaSettings& d) {
    return DeltaParams{d.diagonal_rod_mm,      d.diagonal_rod_trim_mm, d.radius_mm,
                       d.tower_angle_trim_deg, d.endstop_offset_mm,    d.height_mm};
}

models::DeltaSettings machine_settings(const DeltaParams& p) {
    return models::DeltaSettings{p.diagonal_rod_mm,      p.diagonal_rod_trim_mm, p.radius_mm,
                                 p.tower_angle_trim_deg, p.endstop_offset_mm,    p.height_mm};
}

Scenario load_scenario(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw ScenarioError(path + ": cannot read the scenario file");
    std::ostringstream text;
    text << in.rdbuf();
    try {
        return read_scenario(path, models::parse_toml(text.str(), path));
    } catch (const models::MachineFileError& e) {
        throw ScenarioError(e.what());
    }
}

std::unique_ptr<MachineTwin> make_machine_twin(const Scenario& s) {
    return twin_kind_of(s.machine).make_machine(s);
}

RouterVerdict judge_planar_machine(const Scenario& s, const jobs::Correction* correct) {
    return twin_kind_of(s.machine).judge_fresh_job(s, correct);
}

ToolSettings tool_settings_of(const Scenario& s) {
    ToolSettings t;
    t.kind = twin_kind_of(s.machine).tool();
    t.filament_diameter_mm = s.machine.filament_diameter_mm;
    t.layer_height_mm = s.machine.layer_height_mm;
    t.tool_width_mm = s.machine.tool_width_mm;
    t.segment_mm = s.segment_mm;
    t.real_first_layer = s.real_first_layer;
    return t;
}

StrokeSegment material_of(const Stroke& s) {
    return {{s.a_mm.x, s.a_mm.y, s.top_a_mm}, {s.b_mm.x, s.b_mm.y, s.top_b_mm}, s.width_mm};
}

Vec2 PrintedCard::on_bed(Vec2 drawing_mm) const {
    const double a = angle_deg * std::numbers::pi / 180;
    const double x = stretch_x * drawing_mm.x, y = stretch_y * drawing_mm.y;
    return {origin_mm.x + std::cos(a) * x - std::sin(a) * y,
            origin_mm.y + std::sin(a) * x + std::cos(a) * y};
}

}  // namespace calbox::sim
