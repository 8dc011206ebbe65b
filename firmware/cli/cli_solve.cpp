// calbox solve delta: measurements -> machine parameters -> the lines to send.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "core/modes/delta.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/modes/delta_records.hpp"
#include "core/modes/galvo.hpp"
#include "core/modes/planar.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/cli_images.hpp"

namespace calbox::cli {
namespace {

int solve_delta(const Args& args) {
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    if (!machine.is_delta())
        throw std::runtime_error(machine_path + ": solve delta needs a delta machine, not a " +
                                 machine.kind);
    modes::DeltaSolveOptions options;
    options.firmware = args.get("--firmware").value_or(machine.firmware);
    if (options.firmware != "marlin" && options.firmware != "rrf" && options.firmware != "klipper")
        throw UsageError("--firmware must be marlin, rrf or klipper, not '" + options.firmware +
                         "'");
    const std::string method = args.get("--method").value_or("fit");
    if (method != "fit" && method != "classic") throw UsageError("--method must be fit or classic");
    options.method = modes::parse_method(method);
    const std::string measurements_path = args.require("--measurements");
    const auto measurements = modes::measurements_from_json(
        read_input_file(measurements_path, "measurements"), measurements_path);
    std::vector<solve::ProbePoint> probe;
    if (const auto p = args.get("--probe"))
        probe = modes::probe_from_file(read_input_file(*p, "probe file"), *p,
                                       args.get("--probe-radius")
                                           ? std::optional<double>(args.number("--probe-radius", 0))
                                           : std::nullopt);
    modes::DeltaSolution solution;
    try {
        solution = modes::solve_delta(machine, measurements, probe, options);
    } catch (const modes::SolveError& e) {
        throw std::runtime_error(measurements_path + ": " + e.what());
    }
    write_output_file(out, modes::result_to_json(solution));
    const auto& fitted = solution.fit.fitted;
    const auto& correction = solution.fit.correction;
    if (solution.method == modes::DeltaMethod::fit) {
        std::printf(
            "%s: fit correction for %s, fit RMS %.4f mm; predicted XY after %.4f mm RMS, height "
            "map change %.4f mm (bed %.3f mm out of level now: %s)\n",
            out.c_str(), solution.firmware.c_str(), fitted.fit_rms_mm,
            correction.predicted_xy_rms_mm, correction.predicted_height_change_mm,
            correction.predicted_height_range_now_mm, correction.levels_bed ? "levelled" : "kept");
    } else {
        std::printf(
            "%s: classic rod correction for %s from %zu bars: rod %.3f -> %.3f mm (fitted: %.3f "
            "mm)\n",
            out.c_str(), solution.firmware.c_str(), solution.classic_bars,
            fitted.before.diagonal_rod_mm, solution.after.diagonal_rod_mm,
            fitted.estimate.diagonal_rod_mm);
    }
    std::printf("fit: %d iterations, stopped on %s (last step %.1e)%s\n",
                fitted.convergence.iterations, fitted.convergence.stopped_on.c_str(),
                fitted.convergence.final_step,
                fitted.convergence.stopped_on_limit ? ": NOT converged" : "");
    for (const auto& c : solution.commands) std::printf("  %s\n", c.c_str());
    return 0;
}

// The error field before the correction: each node's arrow from where it was commanded to
// where it landed, magnified, over the field; missing marks (filled) in red.
void draw_error_map(const std::string& path, const modes::GalvoSolution& s) {
    const int size_px = 1200, margin_px = 60;
    double half = 0, largest = 0;
    for (std::size_t i = 0; i < s.intended_mm.size(); ++i) {
        half = std::max({half, std::abs(s.intended_mm[i].x), std::abs(s.intended_mm[i].y)});
        largest = std::max(largest, std::hypot(s.fit.landed_mm[i].x - s.intended_mm[i].x,
                                               s.fit.landed_mm[i].y - s.intended_mm[i].y));
    }
    const double px_per_mm = (size_px - 2 * margin_px) / (2 * half);
    double gain = 1;
    for (const double nice : {2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0})
        if (nice * largest * px_per_mm <= 40) gain = nice;
    cv::Mat picture(size_px, size_px, CV_8UC3, cv::Scalar(255, 255, 255));
    const auto to_px = [&](geometry::Point2 p) {
        return cv::Point(cvRound(size_px / 2.0 + p.x * px_per_mm),
                         cvRound(size_px / 2.0 - p.y * px_per_mm));
    };
    const auto& t = s.fit.table;
    cv::rectangle(picture, to_px({t.min_x_mm, t.min_y_mm}), to_px({t.max_x_mm, t.max_y_mm}),
                  cv::Scalar(200, 200, 200), 1);
    for (std::size_t i = 0; i < s.intended_mm.size(); ++i) {
        const auto& q = s.intended_mm[i];
        const auto& p = s.fit.landed_mm[i];
        const geometry::Point2 tip{q.x + gain * (p.x - q.x), q.y + gain * (p.y - q.y)};
        const cv::Scalar colour = s.fit.filled[i] ? cv::Scalar(0, 0, 220) : cv::Scalar(160, 60, 0);
        cv::arrowedLine(picture, to_px(q), to_px(tip), colour, 1, cv::LINE_AA, 0, 0.2);
    }
    char legend[200];
    std::snprintf(legend, sizeof legend,
                  "error before: mean %.4f mm, worst %.4f mm; arrows x%.0f; grey: the table's area",
                  s.fit.before.mean_mm, s.fit.before.max_mm, gain);
    cv::putText(picture, legend, {margin_px / 2, margin_px / 2}, cv::FONT_HERSHEY_SIMPLEX, 0.6,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    write_png(path, picture);
}

int solve_galvo(const Args& args) {
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    const std::string measurements_path = args.require("--measurements");
    const auto measured = modes::galvo_measurements_from_json(
        read_input_file(measurements_path, "measurements"), measurements_path);
    std::optional<modes::GalvoSolution> through;
    if (const auto previous = args.get("--burned-through"))
        through = modes::galvo_result_from_json(read_input_file(*previous, "result"), *previous);
    modes::GalvoSolveOptions options;
    const double nodes = args.number("--table-nodes", 65);
    if (nodes < 2 || nodes > 1025 || nodes != std::floor(nodes))
        throw UsageError("--table-nodes must be a whole number from 2 to 1025");
    options.table_nodes = static_cast<int>(nodes);
    modes::GalvoSolution solution;
    try {
        solution = modes::solve_galvo(machine, measured, through, options);
    } catch (const modes::GalvoError& e) {
        throw std::runtime_error(measurements_path + ": " + e.what());
    } catch (const models::FieldError& e) {
        throw std::runtime_error(measurements_path + ": solve: " + e.what());
    }
    write_output_file(out, modes::galvo_result_to_json(solution));
    if (const auto csv = args.get("--table-csv"))
        write_output_file(*csv, models::table_to_csv(solution.fit.table));
    const auto& t = solution.fit.table;
    std::printf(
        "%s: pass %d; error before %.4f mm mean, %.4f RMS, %.4f worst over %zu marks; "
        "table %d x %d over X %.3f..%.3f Y %.3f..%.3f mm; predicted after %.5f mm RMS "
        "(measurement %.5f, table resolution %.5f worst)\n",
        out.c_str(), solution.pass, solution.fit.before.mean_mm, solution.fit.before.rms_mm,
        solution.fit.before.max_mm, solution.fit.before.points, t.nodes, t.nodes, t.min_x_mm,
        t.max_x_mm, t.min_y_mm, t.max_y_mm, solution.predicted_rms_mm,
        solution.measurement_sigma_mm, solution.fit.table_interpolation_max_mm);
    if (const auto map = args.get("--error-map")) draw_error_map(*map, solution);
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

std::vector<Command> solve_commands() {
    const Option measurements{"--measurements", "measurements.json",
                              "the measurements (calbox measure)", Given::required};
    const Option out{"-o", "result.json", "the result, written", Given::required};
    return {
        {"solve delta",
         "the delta's geometry and the lines that correct it",
         {{"--machine", "printer.toml", "the delta's machine file", Given::required},
          measurements,
          {"--probe", "heights.csv", "measured heights: CSV x,y,z or a firmware's own report"},
          {"--probe-radius", "MM", "a Marlin G33 report's DELTA_CALIBRATION_RADIUS"},
          {"--firmware", "marlin|rrf|klipper", "the lines' dialect (default: the machine file's)"},
          {"--method", "fit|classic", "the fit (default), or the seed paper's rod correction"},
          out},
         R"(Fits the delta's geometry to where its features really landed and writes the correction:
parameters before and after, their uncertainty, what the data determine (singular values,
condition number, parameters held), the residual predicted after correction, and the exact
lines to send. --probe adds measured heights so the height and the height map are
corrected from them: CSV x,y,z (the nozzle's height over the bed when commanded to z = 0
there), or a Marlin console log whose "Bed X: .. Y: .. Z: .." lines G30, or G29 at V3 or
more, printed (the bed's height there, negated), RepRapFirmware's heightmap.csv,
Klipper's printer.cfg with a saved [delta_calibrate], or a Marlin G33 report at V2 or
more (with --probe-radius MM, its DELTA_CALIBRATION_RADIUS). Without it, the heights the first
layer's pressed strands measured from their widths stand in. --method classic is the seed
paper's rod-only correction from the bar lengths, for comparison. Refused, nothing written: measurements
the geometry cannot explain (residual over 3 times their uncertainty), a rod or radius
change over 2 %, a tower angle trim over 3 degrees.)",
         solve_delta},
        {"solve galvo",
         "the scanner's field map and its correction table",
         {{"--machine", "scanner.toml", "the scanner's machine file", Given::required},
          measurements,
          out,
          {"--burned-through", "result.json", "the result whose table the grid was burned through"},
          {"--table-csv", "table.csv", "the table as CSV for a controller, written"},
          {"--table-nodes", "N", "the table's nodes a side (default 65)"},
          {"--error-map", "PNG", "the error field before the correction, drawn"}},
         R"(The scanner's field map from the measured grid and its correction table: the measured
marks turned and shifted onto the commanded grid (the field frame), a C1 bicubic map
through them (missing marks filled from their neighbours and flagged), inverted exactly
at the N x N nodes (default 65) of the largest rectangle inside the measured field. The
result has the error before (mean, RMS, worst), the measurements' uncertainty, what the
table's resolution costs and the table itself; --table-csv writes the table as CSV for a
controller. --burned-through: the result whose table the grid was burned through (a
second pass), refined rather than replaced. Refused, nothing written: a correction over
3 % of the field, or one that would command beyond the field.)",
         solve_galvo},
        {"solve planar",
         "the machine's quasi-static errors and their correction",
         {{"--machine", "machine.toml", "the machine file", Given::required},
          measurements,
          out,
          {"--error-map", "PNG", "each hole's error before and after, drawn"},
          {"--firmware", "FILE", "the firmware's own settings for the part they carry, written"}},
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
         solve_planar},
    };
}

}  // namespace calbox::cli
