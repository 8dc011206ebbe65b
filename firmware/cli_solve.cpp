// calbox solve delta: measurements -> machine parameters -> the lines to send.
#include <cstdio>

#include "core/modes/delta.hpp"
#include "core/modes/delta_records.hpp"
#include "firmware/cli_args.hpp"

namespace calbox::cli {
namespace {

constexpr const char* kSolveHelp = R"(usage:
  calbox solve delta --machine printer.toml --measurements measurements.json [--probe heights.csv]
                     [--firmware marlin|rrf|klipper] [--method fit|classic] -o result.json
      Fits the delta's geometry to where its features really landed and writes the correction:
      parameters before and after, their uncertainty, what the data determine (singular values,
      condition number, parameters held), the residual predicted after correction, and the exact
      lines to send. --probe adds measured heights (CSV x,y,z: the nozzle's height over the bed
      when commanded to z = 0 there) so the height and the height map are corrected too. Without
      it, a bed the fit finds out of level by more than 0.1 mm is levelled about its centre and
      a flatter one keeps the height map it has. --method classic is the seed paper's rod-only
      correction from the bar lengths, for comparison. Refused, nothing written: measurements
      the geometry cannot explain (residual over 3 times their uncertainty), a rod or radius
      change over 2 %, a tower angle trim over 3 degrees.
)";

int delta(const std::vector<std::string>& words) {
    const Args args(words,
                    {"--machine", "--measurements", "--probe", "--firmware", "--method", "-o"}, {});
    if (!args.positional().empty()) throw UsageError("solve delta takes no positional argument");
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
        probe = modes::probe_from_csv(read_input_file(*p, "probe file"), *p);
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
    for (const auto& c : solution.commands) std::printf("  %s\n", c.c_str());
    return 0;
}

}  // namespace

int run_solve(const std::vector<std::string>& words) {
    return dispatch(words, kSolveHelp, "solve", {{"delta", delta}});
}

}  // namespace calbox::cli
