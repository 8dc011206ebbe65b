// calbox target|measure|solve galvo: the galvo scanner's verbs on the command line, in one place.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "core/geometry/camera_model.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_kinds.hpp"
#include "core/modes/galvo.hpp"
#include "core/targets/galvo_target.hpp"
#include "firmware/cli/cli_images.hpp"
#include "firmware/cli/mode_verbs.hpp"
#include "firmware/modes/galvo_mode.hpp"

namespace calbox::cli {
namespace {

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
                               : jobs::write_gcode(target.job, machine,
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

int measure_galvo(const Args& args) {
    const std::string out = args.require("-o");
    const auto [camera, plane, machine] = read_set_up(args);
    modes::GalvoMeasureSettings settings;
    const double grid = args.number("--grid", 31);
    if (grid != std::floor(grid)) throw UsageError("--grid must be a whole number");
    settings.target.grid_count = static_cast<int>(grid);
    const cv::Mat image = load_gray_image(args.positional()[0]);
    auto measured = modes::measure_galvo(machine, camera, plane, view_of(image), settings);
    measured.photos = args.positional();
    write_output_file(out, modes::galvo_measurements_to_json(measured));
    double sigma = 0;
    for (const auto& n : measured.nodes) sigma = std::max(sigma, n.sigma_mm);
    std::printf(
        "%s: %zu of %d marks measured (%s marks), %zu missing, %zu extra blobs; largest "
        "uncertainty %.5f mm\n",
        out.c_str(), measured.nodes.size(), measured.grid_count * measured.grid_count,
        measured.dark_marks ? "dark" : "light", measured.missing.size(), measured.extra_mm.size(),
        sigma);
    for (const auto& m : measured.missing)
        std::printf("  missing: column %d row %d\n", m.column, m.row);
    if (const auto overlay = args.get("--overlay"))
        write_output_file(*overlay, firmware::galvo_overlay_png(view_of(image), measured, machine,
                                                                camera, plane));
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

}  // namespace

ModeVerbs galvo_verbs() {
    ModeVerbs verbs;
    verbs.name = "galvo";
    verbs.machines = models::family_machines(models::MachineFamily::galvo);
    {
        const Option describe = describe_option();
        verbs.target = {
            "target galvo",
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
            target_galvo};
    }
    {
        const Option camera = camera_option();
        const Option plane = plane_option();
        const Option out = measurements_out_option();
        verbs.measure = {
            "measure galvo",
            "the burned circle grid in a photo",
            {camera,
             plane,
             {"--machine", "scanner.toml", "the scanner's machine file", Given::required},
             {"PHOTO", "", "the photo of the burned grid", Given::word},
             out,
             {"--grid", "N", "circles a side, as the grid was made (default 31)"},
             {"--overlay", "overlay.png", "the photo with what was found drawn on it"}},
            R"(Finds the burned circle grid (the target is regenerated from the machine file; --grid as
it was made, default 31): dark marks on a light substrate or light on dark, a median
filter against soot, each mark's centre from fixed-point moments, mapped to the bed at
the substrate's height ([galvo] substrate_height_mm). The grid is indexed by growing it
from its middle mark and turned the way its large marks say; misfired marks are listed
as missing, spatter and damaged marks as extra, and neither stops the measurement. Writes
each mark's commanded centre, where it was measured and its uncertainty. --overlay marks
on the photo the marks used (green), the extra blobs (orange) and each mark's index.)",
            measure_galvo};
    }
    {
        const Option measurements = measurements_option();
        const Option out = result_out_option();
        verbs.solve = {
            "solve galvo",
            "the scanner's field map and its correction table",
            {{"--machine", "scanner.toml", "the scanner's machine file", Given::required},
             measurements,
             out,
             {"--burned-through", "result.json",
              "the result whose table the grid was burned through"},
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
            solve_galvo};
    }
    return verbs;
}

}  // namespace calbox::cli
