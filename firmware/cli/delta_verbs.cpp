// calbox target|measure|solve delta: the delta printer's verbs on the command line, in one place.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>

#include "core/geometry/camera_model.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_kinds.hpp"
#include "core/modes/delta.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/modes/delta_records.hpp"
#include "core/targets/delta_target.hpp"
#include "firmware/cli/cli_images.hpp"
#include "firmware/cli/mode_verbs.hpp"
#include "firmware/modes/delta_mode.hpp"

namespace calbox::cli {
namespace {

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
    write_output_file(
        out, jobs::write_gcode(target.job, machine, "calbox target delta " + target.fingerprint));
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

int measure_delta(const Args& args) {
    const std::string out = args.require("-o");
    const auto [camera, plane, machine] = read_set_up(args);
    std::vector<cv::Mat> images;
    std::vector<vision::GrayView> views;
    images.reserve(args.positional().size());
    views.reserve(args.positional().size());
    for (const auto& path : args.positional()) images.push_back(load_gray_image(path));
    for (const auto& image : images) views.push_back(view_of(image));
    std::optional<double> photo_bed_temperature_c;
    if (args.get("--bed-temperature")) {
        photo_bed_temperature_c = args.number("--bed-temperature", 0);
        if (*photo_bed_temperature_c < -50 || *photo_bed_temperature_c > 200)
            throw UsageError("--bed-temperature must be -50..200 degrees C");
    }
    const auto measured =
        modes::measure_delta(machine, camera, plane, views, photo_bed_temperature_c);
    write_output_file(
        out, modes::measurements_to_json(modes::record_of(measured, machine, args.positional())));
    std::printf("%s: %zu corners of %zu markers from %zu photo(s)\n", out.c_str(),
                measured.features.size(), measured.target.markers.size(), views.size());
    if (!measured.heights_from_fit) std::printf("heights: %s\n", measured.heights_fallback.c_str());
    for (const auto& why : measured.bars_unmeasured) std::printf("not measured: %s\n", why.c_str());
    for (const auto& why : measured.markers_unread) std::printf("not read: %s\n", why.c_str());
    for (const auto& why : measured.rings_unmeasured)
        std::printf("not measured: %s\n", why.c_str());
    for (const auto& why : measured.heights_unmeasured)
        std::printf("height from the surface fit: %s\n", why.c_str());
    const auto unrefined = std::count_if(measured.features.begin(), measured.features.end(),
                                         [](const auto& f) { return !f.refined; });
    if (unrefined > 0) {
        std::printf("%ld corners kept as the detector found them (refined: false):\n",
                    static_cast<long>(unrefined));
        for (std::size_t f = 0; f < measured.frames.size(); ++f) {
            for (const auto& m : measured.frames[f]) {
                if (!m.refined)
                    std::printf("  photo %zu, marker %d: %s\n", f + 1, m.id,
                                m.unrefined_because.c_str());
            }
        }
    }
    for (const auto& b : measured.bars) {
        std::printf("bar %c: %.3f mm between its end ticks (+/- %.3f), commanded %.3f\n", b.tower,
                    b.measured_mm, b.sigma_mm, b.commanded_mm);
    }
    if (const auto overlay = args.get("--overlay"))
        write_output_file(*overlay,
                          firmware::delta_overlay_png(views.front(), measured, camera, plane));
    return 0;
}

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

}  // namespace

ModeVerbs delta_verbs() {
    ModeVerbs verbs;
    verbs.name = "delta";
    verbs.machines = models::family_machines(models::MachineFamily::delta);
    {
        const Option describe = describe_option();
        verbs.target = {
            "target delta",
            "the delta's calibration artifact, as G-code",
            {{"--machine", "printer.toml", "the delta's machine file", Given::required},
             {"-o", "target.gcode", "the job, written", Given::required},
             {"--preview", "target.png", "the artifact, drawn"},
             describe,
             {"--layers", "N", "layers printed, 1 to 5 (default 1)"}},
            R"(The delta calibration artifact: ArUco markers (DICT_4X4_50, 12 mm) spread over the bed,
their white cells filled as zigzag lines at the line width, each ringed by one strand, and
three bars along the towers with one strand across each end. --describe writes each feature's commanded position in machine millimetres.)",
            target_delta};
    }
    {
        const Option camera = camera_option();
        const Option plane = plane_option();
        const Option out = measurements_out_option();
        verbs.measure = {
            "measure delta",
            "the delta's printed target in photos",
            {camera,
             plane,
             {"--machine", "printer.toml", "the delta's machine file", Given::required},
             {"IMAGES", "", "photos of the printed target", Given::words},
             out,
             {"--overlay", "overlay.png", "the first photo with what was found drawn on it"},
             {"--bed-temperature", "C", "the bed's temperature when the photos were taken"}},
            R"(Finds the delta target's markers in the photos (the target is regenerated from the machine
file), refines their corners, maps them to the bed and moves each along its ray to the
printed surface's height (from a fit of the corners), and writes each corner's commanded
and measured position with its uncertainty. Several photos are averaged. The three bars
are measured between the centrelines of the single strands across their ends. --bed-temperature: the
bed's temperature when the photos were taken (default: the machine file's
photo_bed_temperature_c), if not the bed_temperature_c it printed at; the print has grown or shrunk with the bed (bed_material) and positions are
given as printed. --overlay draws on the first photo what was found, each corner's error
after the best rotation and translation, magnified 10 to 1000 times (the factor is written
on the picture), and each bar with its length and its difference from the commanded one.)",
            measure_delta};
    }
    {
        const Option measurements = measurements_option();
        const Option out = result_out_option();
        verbs.solve = {
            "solve delta",
            "the delta's geometry and the lines that correct it",
            {{"--machine", "printer.toml", "the delta's machine file", Given::required},
             measurements,
             {"--probe", "heights.csv", "measured heights: CSV x,y,z or a firmware's own report"},
             {"--probe-radius", "MM", "a Marlin G33 report's DELTA_CALIBRATION_RADIUS"},
             {"--firmware", "marlin|rrf|klipper",
              "the lines' dialect (default: the machine file's)"},
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
            solve_delta};
    }
    return verbs;
}

}  // namespace calbox::cli
