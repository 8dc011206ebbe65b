// calbox target|measure|solve planar: the router, cartesian printer or gantry laser's verbs on the
// command line, in one place.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "core/geometry/camera_model.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_kinds.hpp"
#include "core/modes/planar.hpp"
#include "core/targets/planar_target.hpp"
#include "firmware/cli/cli_images.hpp"
#include "firmware/cli/mode_verbs.hpp"
#include "firmware/modes/planar_mode.hpp"

namespace calbox::cli {
namespace {

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

int measure_planar(const Args& args) {
    const std::string out = args.require("-o");
    const auto [camera, plane, machine] = read_set_up(args);
    modes::PlanarMeasureSettings settings;
    if (args.get("--design")) {
        const double n = args.number("--design", 0);
        if (n != std::floor(n) || n < 1) throw UsageError("--design must be a whole number");
        settings.target.only_nodes =
            modes::planar_design_nodes(machine, static_cast<std::size_t>(n));
    }
    std::vector<geometry::Point2> offsets(args.positional().size());
    if (const auto text = args.get("--offsets")) {
        offsets.clear();
        std::size_t start = 0;
        while (start <= text->size()) {
            const std::size_t end = std::min(text->find(';', start), text->size());
            const std::string pair = text->substr(start, end - start);
            double x = 0, y = 0;
            char tail = 0;
            if (std::sscanf(pair.c_str(), "%lf,%lf%c", &x, &y, &tail) != 2 || !std::isfinite(x) ||
                !std::isfinite(y))
                throw UsageError("--offsets takes X,Y pairs separated by ';', not '" + pair + "'");
            offsets.push_back({x, y});
            start = end + 1;
        }
        if (offsets.size() != args.positional().size())
            throw UsageError("--offsets gives " + std::to_string(offsets.size()) +
                             " positions for " + std::to_string(args.positional().size()) +
                             " photos");
    } else if (args.positional().size() > 1) {
        throw UsageError("several photos need --offsets: where the machine put the camera");
    }
    std::vector<cv::Mat> images;
    for (const auto& path : args.positional()) images.push_back(load_gray_image(path));
    std::vector<modes::PlanarView> views;
    for (std::size_t i = 0; i < images.size(); ++i)
        views.push_back({view_of(images[i]), offsets[i]});
    const cv::Mat& image = images.front();
    auto measured = modes::measure_planar_views(machine, camera, plane, views, settings);
    measured.photos = args.positional();
    write_output_file(out, modes::planar_measurements_to_json(measured));
    double sigma = 0;
    for (const auto& h : measured.holes) sigma = std::max(sigma, h.sigma_mm);
    std::printf(
        "%s: %zu holes measured, %zu missing, %zu extra blobs%s; largest uncertainty "
        "%.5f mm\n",
        out.c_str(), measured.holes.size(), measured.missing.size(), measured.extra_mm.size(),
        measured.mirrored ? " (the photo's frame mirrored)" : "", sigma);
    for (const auto& m : measured.missing)
        std::printf("  missing: column %d row %d\n", m.column, m.row);
    if (const auto overlay = args.get("--overlay"))
        write_output_file(*overlay, firmware::planar_overlay_png(view_of(image), measured, machine,
                                                                 camera, plane));
    return 0;
}

void draw_planar_error_map(const std::string& path, const modes::PlanarSolution& s) {
    const int size_px = 1200, margin_px = 70;
    double largest = 0;
    for (const auto& e : s.error_mm) largest = std::max(largest, std::hypot(e.x, e.y));
    const double span = std::max(s.max_x_mm - s.min_x_mm, s.max_y_mm - s.min_y_mm);
    const double px_per_mm = (size_px - 2 * margin_px) / span;
    double gain = 1;
    for (const double nice : {2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0})
        if (nice * largest * px_per_mm <= 60) gain = nice;
    cv::Mat picture(size_px, size_px, CV_8UC3, cv::Scalar(255, 255, 255));
    const auto to_px = [&](geometry::Point2 p) {
        return cv::Point(cvRound(margin_px + (p.x - s.min_x_mm) * px_per_mm),
                         cvRound(size_px - margin_px - (p.y - s.min_y_mm) * px_per_mm));
    };
    for (std::size_t i = 0; i < s.commanded_mm.size(); ++i) {
        const auto& q = s.commanded_mm[i];
        const auto draw = [&](geometry::Point2 e, const cv::Scalar& colour) {
            cv::arrowedLine(picture, to_px(q), to_px({q.x + gain * e.x, q.y + gain * e.y}), colour,
                            2, cv::LINE_AA, 0, 0.2);
        };
        draw(s.error_mm[i], cv::Scalar(0, 0, 220));
        draw(s.fit.residuals_mm[i], cv::Scalar(0, 160, 0));
    }
    char legend[240];
    std::snprintf(legend, sizeof legend,
                  "error norm before (red): mean %.4f mm, max %.4f; after (green): mean %.4f, "
                  "max %.4f; arrows x%.0f",
                  s.before.mean_mm, s.before.max_mm, s.after.mean_mm, s.after.max_mm, gain);
    cv::putText(picture, legend, {margin_px / 3, margin_px / 2}, cv::FONT_HERSHEY_SIMPLEX, 0.55,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    write_png(path, picture);
}

int solve_planar(const Args& args) {
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    const std::string measurements_path = args.require("--measurements");
    const auto measured = modes::planar_measurements_from_json(
        read_input_file(measurements_path, "measurements"), measurements_path);
    modes::PlanarSolution solution;
    try {
        solution = modes::solve_planar(machine, measured);
    } catch (const modes::PlanarError& e) {
        throw std::runtime_error(measurements_path + ": " + e.what());
    } catch (const models::PlanarModelError& e) {
        throw std::runtime_error(measurements_path + ": solve: " + e.what());
    }
    const auto firmware = modes::planar_firmware_settings(machine, solution);
    write_output_file(out, modes::planar_result_to_json(solution, firmware));
    if (const auto path = args.get("--firmware")) {
        std::string text;
        for (const auto& line : firmware.lines) text += line + "\n";
        write_output_file(*path, text);
    }
    const auto& b = solution.before;
    const auto& a = solution.after;
    std::printf(
        "%s: %zu holes, fit residual %.4f mm RMS (measurement %.4f mm), rank %d, "
        "condition %.0f\n",
        out.c_str(), b.points, solution.fit.residual_rms_mm, solution.measurement_sigma_mm,
        solution.fit.rank, solution.fit.condition);
    std::printf("  error norm   max     Q3      median  Q1      min     mean    std\n");
    std::printf("  before    %7.4f %7.4f %7.4f %7.4f %7.4f %7.4f %7.4f mm\n", b.max_mm, b.q3_mm,
                b.median_mm, b.q1_mm, b.min_mm, b.mean_mm, b.std_mm);
    std::printf("  after     %7.4f %7.4f %7.4f %7.4f %7.4f %7.4f %7.4f mm (predicted)\n", a.max_mm,
                a.q3_mm, a.median_mm, a.q1_mm, a.min_mm, a.mean_mm, a.std_mm);
    const auto& names = models::planar_parameters();
    for (std::size_t j = 0; j < names.size(); ++j) {
        if (solution.fit.fitted[j]) {
            std::printf("  %-18s %+.4e +- %.1e %s\n", names[j].name, solution.fit.parameters[j],
                        solution.fit.uncertainty[j], names[j].unit);
            continue;
        }
        for (const auto& h : solution.fit.held)
            if (h.parameter == static_cast<int>(j))
                std::printf("  %-18s held: absorbed by %s\n", names[j].name, h.absorbed_by.c_str());
    }
    for (const auto& line : firmware.lines) std::printf("  %s\n", line.c_str());
    if (const auto map = args.get("--error-map")) draw_planar_error_map(*map, solution);
    return 0;
}

}  // namespace

ModeVerbs planar_verbs() {
    ModeVerbs verbs;
    verbs.name = "planar";
    verbs.machines = models::family_machines(models::MachineFamily::planar);
    {
        const Option describe = describe_option();
        verbs.target = {
            "target planar",
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
            target_planar};
    }
    {
        const Option camera = camera_option();
        const Option plane = plane_option();
        const Option out = measurements_out_option();
        verbs.measure = {
            "measure planar",
            "the drilled or printed hole grid in photos",
            {camera,
             plane,
             {"--machine", "machine.toml", "the machine file", Given::required},
             {"PHOTOS", "", "photos of the sheet", Given::words},
             out,
             {"--offsets", "X,Y;X,Y...", "where the machine put the camera for each photo (mm)"},
             {"--design", "N", "the number of holes, as the grid was made"},
             {"--overlay", "overlay.png", "the first photo with what was found drawn on it"}},
            R"(Finds the drilled (or printed) hole grid (the target is regenerated from the machine file;
--design as it was made): each hole's centre from fixed-point moments, mapped to the bed at
the sheet's top ([planar] surface_height_mm); the grid placed by its two large holes (all
four ways round are tried) and every hole matched where the placement puts it. Holes with
a chip or a burr (elongated, or 5 % off their kind's size) are listed as extra and their
node as missing; two holes where the grid has one, a photo of another grid, or one that
shows under three quarters of it: one line, nothing written. A sheet larger than one view:
several photos from a camera the machine carries, --offsets giving where the machine put
it for each (machine mm; the first photo shows the two large holes and is the one --plane
was taken from). The offsets only say which hole is which; the photos are stitched through
the holes they share (each photo's rotation and shift fitted), so the machine's own errors
in moving the camera do not enter. --overlay marks, on the first photo, the holes used
(green), the extra blobs (orange) and the large holes' indices.)",
            measure_planar};
    }
    {
        const Option measurements = measurements_option();
        const Option out = result_out_option();
        verbs.solve = {
            "solve planar",
            "the machine's quasi-static errors and their correction",
            {{"--machine", "machine.toml", "the machine file", Given::required},
             measurements,
             out,
             {"--error-map", "PNG", "each hole's error before and after, drawn"},
             {"--firmware", "FILE",
              "the firmware's own settings for the part they carry, written"}},
            R"(The machine's quasi-static errors from the measured holes (the large ones only place the
grid): the twelve parameters of a gantry's kinematic chain to first order (scales,
squareness, straightness, gantry yaw, pitch and roll over [planar] tool_length_mm, the
tool's tilt), fitted by least squares with the machine's placement in the photo beside
them; those the holes cannot tell apart from others are held at 0 and reported with what
absorbs them. The result has each parameter with its uncertainty, the seed paper's
statistics of the error norm (max, Q3, median, Q1, min, mean, std) before and after (the
fit's residuals: what the correction leaves at the holes), the area it is valid over,
and the firmware's own settings for the part they can carry (Marlin M92 and M852, Klipper
rotation_distance and SET_SKEW, grbl $100/$101, LinuxCNC compensation files) with what
they leave. calbox compensate applies the whole model to any job. --error-map draws each
hole's error before (red) and after (green), magnified. --firmware writes those settings.
Refused, nothing written: a hole over 10 mm from where it was commanded, a correction
that large anywhere in the area, fewer than 8 holes, a design too badly conditioned.)",
            solve_planar};
    }
    return verbs;
}

}  // namespace calbox::cli
