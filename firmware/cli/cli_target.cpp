// calbox target svg: a job for any machine from a drawing.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "core/models/machine_file.hpp"
#include "core/modes/planar.hpp"
#include "core/targets/delta_target.hpp"
#include "core/targets/galvo_target.hpp"
#include "core/targets/job.hpp"
#include "core/targets/planar_target.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/cli_images.hpp"

namespace calbox::cli {
namespace {

constexpr std::uintmax_t kMaxSvgBytes = std::uintmax_t{10} * 1024 * 1024;

void draw_preview(const std::string& path, const targets::PlacedJob& job,
                  const models::MachineFile& machine) {
    const double margin_mm = 2 + job.line_width_mm;
    const double width_mm = job.max_x - job.min_x + 2 * margin_mm,
                 height_mm = job.max_y - job.min_y + 2 * margin_mm;
    const double px_per_mm = 1200.0 / std::max(width_mm, height_mm);
    const int text_rows = 70;
    cv::Mat picture(static_cast<int>(height_mm * px_per_mm) + text_rows,
                    static_cast<int>(width_mm * px_per_mm), CV_8UC3, cv::Scalar(255, 255, 255));
    constexpr int kShift = 4;  // sub-pixel drawing
    const auto to_px = [&](geometry::Point2 p) {
        return cv::Point(static_cast<int>(std::lround((p.x - job.min_x + margin_mm) * px_per_mm *
                                                      (1 << kShift))),
                         static_cast<int>(std::lround((job.max_y + margin_mm - p.y) * px_per_mm *
                                                      (1 << kShift))));
    };
    const int line_px = std::max(1, static_cast<int>(std::lround(job.line_width_mm * px_per_mm)));
    for (const auto& move : job.toolpath.moves) {
        cv::Scalar colour(0, 0, 220);  // travel
        int thickness = 1;
        if (move.kind == targets::MoveKind::perimeter) colour = cv::Scalar(200, 90, 0);
        if (move.kind == targets::MoveKind::infill) colour = cv::Scalar(60, 170, 60);
        if (move.kind == targets::MoveKind::trace) colour = cv::Scalar(160, 40, 160);
        if (move.kind != targets::MoveKind::travel) thickness = line_px;
        cv::line(picture, to_px(move.from), to_px(move.to), colour, thickness, cv::LINE_AA, kShift);
    }
    char text[256];
    std::snprintf(text, sizeof text,
                  "path %.1f mm, travel %.1f mm (%.1f %%), about %.0f s at %.0f mm/s",
                  job.toolpath.working_length_mm(), job.toolpath.travel_length_mm(),
                  100 * job.toolpath.travel_length_mm() / job.toolpath.working_length_mm(),
                  job.estimated_time_s(machine), job.feed_mm_s);
    cv::putText(picture, text, cv::Point(10, picture.rows - 40), cv::FONT_HERSHEY_SIMPLEX, 0.6,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    std::snprintf(
        text, sizeof text,
        "%.2f x %.2f mm, line %.3f mm, spacing %.3f mm; blue perimeters, green infill, red travel",
        job.max_x - job.min_x, job.max_y - job.min_y, job.line_width_mm, job.spacing_mm);
    cv::putText(picture, text, cv::Point(10, picture.rows - 15), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    write_png(path, picture);
}

int target_svg(const Args& args) {
    const std::string svg_path = args.positional()[0];
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    targets::SvgJobSettings settings;
    if (args.get("--spacing")) settings.spacing_mm = args.number("--spacing", 0);
    if (args.get("--angle")) settings.angle_deg = args.number("--angle", 0);
    if (args.get("--feed")) settings.feed_mm_s = args.number("--feed", 0);
    if (args.get("--scale")) settings.scale = args.number("--scale", 0);
    if (args.get("--fit")) settings.fit_mm = args.number("--fit", 0);
    settings.perimeters = static_cast<int>(args.number("--perimeters", 1));
    if (const auto rule = args.get("--fill-rule")) {
        if (*rule != "nonzero" && *rule != "evenodd")
            throw UsageError("--fill-rule must be nonzero or evenodd");
        settings.fill_rule =
            *rule == "evenodd" ? targets::FillRule::evenodd : targets::FillRule::nonzero;
    }
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    std::error_code error;
    const auto size = std::filesystem::file_size(svg_path, error);
    if (!error && size > kMaxSvgBytes) {
        throw std::runtime_error(svg_path + ": the document is " + std::to_string(size) +
                                 " bytes, over the limit of " + std::to_string(kMaxSvgBytes));
    }
    targets::SvgDocument document;
    try {
        document = targets::parse_svg(read_input_file(svg_path, "drawing"));
    } catch (const targets::SvgError& e) {
        throw std::runtime_error(svg_path + ": " + e.what());
    }
    for (const auto& warning : document.warnings)
        std::fprintf(stderr, "calbox: warning: %s: %s\n", svg_path.c_str(), warning.c_str());
    const auto job = targets::plan_svg_job(document, machine, settings);
    if (job.shapes_cut_at_page > 0)
        std::fprintf(stderr,
                     "calbox: warning: %s: %d shapes reach past the drawing's page and were cut at "
                     "its edge, as a browser shows them\n",
                     svg_path.c_str(), job.shapes_cut_at_page);
    write_output_file(
        out, targets::write_gcode(
                 job, machine,
                 "calbox target svg " + std::filesystem::path(svg_path).filename().string()));
    std::printf("%s: %.2f x %.2f mm, %zu moves, path %.1f mm, travel %.1f mm, about %.0f s\n",
                out.c_str(), job.max_x - job.min_x, job.max_y - job.min_y,
                job.toolpath.moves.size(), job.toolpath.working_length_mm(),
                job.toolpath.travel_length_mm(), job.estimated_time_s(machine));
    if (const auto preview = args.get("--preview")) draw_preview(*preview, job, machine);
    return 0;
}

int target_delta(const Args& args) {
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    targets::DeltaTargetOptions options;
    const double layers = args.number("--layers", 1);
    if (layers < 1 || layers > 5 || layers != std::floor(layers))
        throw UsageError("--layers must be 1 to 5");
    options.layers = static_cast<int>(layers);
    const auto target = targets::make_delta_target(machine, options);
    write_output_file(out, targets::write_gcode(target.job, machine,
                                                "calbox target delta " + target.fingerprint));
    if (const auto describe = args.get("--describe")) {
        const auto point = [](geometry::Point2 p) { return nlohmann::json::array({p.x, p.y}); };
        nlohmann::json markers = nlohmann::json::array(), bars = nlohmann::json::array();
        for (const auto& m : target.markers) {
            nlohmann::json corners = nlohmann::json::array();
            for (const auto& c : m.corners_mm) corners.push_back(point(c));
            nlohmann::json ring = nlohmann::json::array();
            for (const auto& c : m.outline_corners_mm) ring.push_back(point(c));
            markers.push_back({{"id", m.id},
                               {"centre_mm", point(m.centre_mm)},
                               {"corners_mm", corners},
                               {"ring_corners_mm", ring}});
        }
        for (const auto& b : target.bars) {
            bars.push_back({{"tower", std::string(1, b.tower)},
                            {"start_mm", point(b.start_mm)},
                            {"end_mm", point(b.end_mm)},
                            {"width_mm", b.width_mm},
                            {"ticks_mm", {point(b.ticks_mm[0]), point(b.ticks_mm[1])}},
                            {"length_mm", b.length_mm()}});
        }
        const nlohmann::json j{{"schema", "calbox.target/1"},
                               {"target_fingerprint", target.fingerprint},
                               {"machine_fingerprint", models::fingerprint(machine)},
                               {"dictionary", options.dictionary},
                               {"marker_mm", options.marker_mm},
                               {"top_height_mm", target.top_height_mm},
                               {"markers", markers},
                               {"bars", bars}};
        write_output_file(*describe, j.dump(1) + "\n");
    }
    std::printf(
        "%s: %zu markers, 3 bars, %d layer(s), path %.1f mm, travel %.1f mm, about %.1f min\n",
        out.c_str(), target.markers.size(), options.layers,
        target.job.toolpath.working_length_mm() * options.layers,
        target.job.toolpath.travel_length_mm() * options.layers,
        target.job.estimated_time_s(machine) * options.layers / 60);
    if (const auto preview = args.get("--preview")) draw_preview(*preview, target.job, machine);
    return 0;
}

int target_galvo(const Args& args) {
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    const std::string format = args.get("--format").value_or("gcode");
    if (format != "gcode" && format != "csv") throw UsageError("--format must be gcode or csv");
    const double grid = args.number("--grid", 31);
    if (grid != std::floor(grid)) throw UsageError("--grid must be a whole number");
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    const auto target = targets::make_galvo_target(machine, {static_cast<int>(grid)});
    write_output_file(out, format == "csv"
                               ? targets::write_scanner_job_csv(target.job, machine)
                               : targets::write_gcode(target.job, machine,
                                                      "calbox target galvo " + target.fingerprint));
    if (const auto describe = args.get("--describe")) {
        nlohmann::json marks = nlohmann::json::array();
        for (const auto& m : target.marks)
            marks.push_back({{"column", m.index.column},
                             {"row", m.index.row},
                             {"centre_mm", {m.centre_mm.x, m.centre_mm.y}},
                             {"radius_mm", (m.large ? 0.4 : 0.2) * target.pitch_mm},
                             {"large", m.large}});
        const nlohmann::json j{{"schema", "calbox.galvo-target/1"},
                               {"target_fingerprint", target.fingerprint},
                               {"machine_fingerprint", models::fingerprint(machine)},
                               {"grid_count", target.grid_count},
                               {"pitch_mm", target.pitch_mm},
                               {"marks", marks}};
        write_output_file(*describe, j.dump(1) + "\n");
    }
    std::printf("%s: %d x %d circles at %.4f mm pitch, path %.1f mm, about %.0f s\n", out.c_str(),
                target.grid_count, target.grid_count, target.pitch_mm,
                target.job.toolpath.working_length_mm(), target.job.estimated_time_s(machine));
    if (const auto preview = args.get("--preview")) draw_preview(*preview, target.job, machine);
    return 0;
}

int target_planar(const Args& args) {
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    targets::PlanarTargetOptions options;
    if (args.get("--design")) {
        const double n = args.number("--design", 0);
        if (n != std::floor(n) || n < 1) throw UsageError("--design must be a whole number");
        options.only_nodes = modes::planar_design_nodes(machine, static_cast<std::size_t>(n));
    }
    const auto target = targets::make_planar_target(machine, options);
    write_output_file(out, target.job);
    if (const auto describe = args.get("--describe")) {
        nlohmann::json holes = nlohmann::json::array();
        for (const auto& h : target.holes)
            holes.push_back(
                {{"column", h.index.column},
                 {"row", h.index.row},
                 {"centre_mm", {h.centre_mm.x, h.centre_mm.y}},
                 {"diameter_mm", h.large ? target.large_diameter_mm : target.hole_diameter_mm},
                 {"large", h.large}});
        const nlohmann::json j{{"schema", "calbox.planar-target/1"},
                               {"target_fingerprint", target.fingerprint},
                               {"machine_fingerprint", models::fingerprint(machine)},
                               {"columns", target.columns},
                               {"rows", target.rows},
                               {"pitch_mm", target.pitch_mm},
                               {"omitted", {target.omitted.column, target.omitted.row}},
                               {"holes", holes}};
        write_output_file(*describe, j.dump(1) + "\n");
    }
    std::printf("%s: %d x %d grid at %.3f mm, %zu holes of %.3f mm (two of %.3f mm)%s%s\n",
                out.c_str(), target.columns, target.rows, target.pitch_mm, target.holes.size(),
                target.hole_diameter_mm, target.large_diameter_mm,
                target.backlash_hole ? ", and one more for the backlash" : "",
                options.only_nodes ? ", a DETMAX design" : "");
    return 0;
}

}  // namespace

std::vector<Command> target_commands() {
    const Option describe{"--describe", "target.json",
                          "every feature's commanded position, written"};
    return {
        {"target delta",
         "the delta's calibration artifact, as G-code",
         {{"--machine", "printer.toml", "the delta's machine file", Given::required},
          {"-o", "target.gcode", "the job, written", Given::required},
          {"--preview", "target.png", "the artifact, drawn"},
          describe,
          {"--layers", "N", "layers printed, 1 to 5 (default 1)"}},
         R"(The delta calibration artifact: ArUco markers (DICT_4X4_50, 12 mm) spread over the bed,
their white cells filled as zigzag lines at the line width, each ringed by one strand, and
three bars along the towers with one strand across each end. --describe writes each feature's commanded position in machine millimetres.)",
         target_delta},
        {"target galvo",
         "the scanner's burned circle grid, as a job",
         {{"--machine", "scanner.toml", "the scanner's machine file", Given::required},
          {"-o", "JOB", "the job, written", Given::required},
          {"--format", "gcode|csv", "G-code (default) or a plain scanner job"},
          {"--grid", "N", "circles a side (default 31)"},
          {"--preview", "PNG", "the grid, drawn"},
          describe},
         R"(The galvo calibration artifact: an N x N grid (default 31) of filled circles over the
field ([galvo] field_size_mm), pitch field / N, small ones of 0.2 pitch radius and eight
large ones of 0.4 pitch laid out so that no rotation or mirror image matches. --format
gcode (default: M3/M5 with power, G1 at feed_mm_s, in scanner millimetres) or csv (a
plain scanner job: x_mm,y_mm,power lines). --describe writes every mark's commanded
centre, its grid index and its size.)",
         target_galvo},
        {"target planar",
         "the router's, cartesian printer's or laser's hole grid, as G-code",
         {{"--machine", "machine.toml", "the machine file", Given::required},
          {"-o", "target.gcode", "the job, written", Given::required},
          {"--design", "N", "only the N holes best for the model, for a short job"},
          describe},
         R"(The planar calibration artifact for a router, cartesian printer or laser: a grid of holes
over the work area at [planar] hole_pitch_mm, the outer ones margin_mm inside it. Routers
drill them with their tool (tool_width_mm), plunging to cut_depth_mm at plunge_feed_mm_s
with a dwell of dwell_s, every hole approached from -X -Y so the drives' slack is taken up
alike, in the firmware's dialect (grbl, linuxcnc: G4 in seconds and M2; marlin: G4 in ms);
Z0 is the sheet's top. Printers and lasers fill dots a quarter pitch across. Two holes near
the first corner are twice the size and one is left out, so a photo says which hole is
which. --design N: only the N holes (and the two large ones) that DETMAX finds best for
the model, for a short job; measure with the same --design. --describe writes every hole's
commanded centre, grid index and diameter.)",
         target_planar},
        {"target svg",
         "a job for the machine from a drawing",
         {{"FILE.svg", "", "the drawing", Given::word},
          {"--machine", "FILE", "the machine file", Given::required},
          {"-o", "JOB", "the job, written", Given::required},
          {"--spacing", "MM", "infill lines apart (default: the line width)"},
          {"--angle", "DEG", "the infill's direction"},
          {"--feed", "MM_S", "the working feed"},
          {"--scale", "S", "the drawing's own size times S"},
          {"--fit", "MM", "the drawing's larger side, in mm"},
          {"--fill-rule", "nonzero|evenodd", "for every filled shape (default: each shape's own)"},
          {"--perimeters", "N", "perimeters around each filled shape (default 1)"},
          {"--preview", "PNG", "the job's paths, drawn"}},
         R"(A job for the machine from a drawing. Filled shapes are filled as SVG means it (their
fill-rule, or --fill-rule for all): perimeters inset by half the line width, then infill
lines --spacing apart (default: the line width; printers accept their line width to ten
times it) at --angle degrees, in a zigzag. Shapes with only a stroke are traced. The
drawing is centred on the bed and reads as drawn seen from above; --fit makes its larger
side that many mm, --scale multiplies its own size. --preview draws perimeters (blue),
infill (green), traces (purple) and travel (red) with path length, travel and time.)",
         target_svg},
    };
}

}  // namespace calbox::cli
