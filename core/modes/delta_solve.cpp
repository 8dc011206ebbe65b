// The delta mode's solve and what measure leaves for it, without the command line: the
// appliance and `calbox solve` call these.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/geometry/placement.hpp"
#include "core/models/delta_commands.hpp"
#include "core/modes/delta.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {

DeltaMeasurementsRecord record_of(const DeltaMeasurement& measured,
                                  const models::MachineFile& machine,
                                  std::vector<std::string> photos) {
    DeltaMeasurementsRecord r;
    r.machine_fingerprint = models::fingerprint(machine);
    r.target_fingerprint = measured.target.fingerprint;
    r.photos = std::move(photos);
    r.bed_scale = measured.bed_scale;
    r.heights_from_fit = measured.heights_from_fit;
    r.heights_fallback = measured.heights_fallback;
    r.bars_unmeasured = measured.bars_unmeasured;
    r.heights_unmeasured = measured.heights_unmeasured;
    r.features = measured.features;
    r.bars = measured.bars;
    return r;
}

PlacementErrors placement_errors(const std::vector<solve::FeatureMeasurement>& features) {
    PlacementErrors out;
    if (features.size() < 2) return out;
    std::vector<geometry::Point2> commanded, seen;
    for (const auto& f : features)
        commanded.push_back({f.commanded_mm.x, f.commanded_mm.y}), seen.push_back(f.measured_mm);
    out.placement = geometry::best_rigid_placement(commanded, seen);
    double sum = 0;
    for (std::size_t i = 0; i < features.size(); ++i) {
        const auto placed = out.placement.apply(commanded[i]);
        const geometry::Point2 e{seen[i].x - placed.x, seen[i].y - placed.y};
        out.error_mm.push_back(e);
        sum += e.x * e.x + e.y * e.y;
        out.largest_mm = std::max(out.largest_mm, std::hypot(e.x, e.y));
    }
    out.rms_mm = std::sqrt(sum / static_cast<double>(features.size()));
    return out;
}

std::string method_name(DeltaMethod method) {
    return method == DeltaMethod::classic ? "classic" : "fit";
}

DeltaMethod parse_method(const std::string& name) {
    if (name == "fit") return DeltaMethod::fit;
    if (name == "classic") return DeltaMethod::classic;
    throw SolveError("the method must be fit or classic, not '" + name + "'");
}

DeltaSolution solve_delta(const models::MachineFile& machine,
                          const DeltaMeasurementsRecord& measurements,
                          const std::vector<solve::ProbePoint>& probe,
                          const DeltaSolveOptions& options) {
    if (!machine.is_delta())
        throw SolveError("the delta solve needs a delta machine, not a " + machine.kind);
    DeltaSolution s;
    s.method = options.method;
    s.firmware = options.firmware.empty() ? machine.firmware : options.firmware;
    if (s.firmware != "marlin" && s.firmware != "rrf" && s.firmware != "klipper") {
        throw SolveError("the delta solve writes for marlin, rrf or klipper, not '" + s.firmware +
                         "'");
    }
    s.heights_from_probe = !probe.empty();
    // Without a probe, the heights the strands' widths measured.
    const auto heights =
        probe.empty() ? solve::strand_heights_as_probe(measurements.features) : probe;
    s.machine_fingerprint = models::fingerprint(machine);
    if (measurements.machine_fingerprint != s.machine_fingerprint) {
        throw SolveError("the measurements were made for another machine (fingerprint " +
                         measurements.machine_fingerprint + ", this machine is " +
                         s.machine_fingerprint + ")");
    }
    if (s.method == DeltaMethod::fit) {
        try {
            s.fit = solve::fit_delta(machine, measurements.features, heights, machine.delta_limits);
        } catch (const solve::FitError& e) {
            // The measurement's own fit of the surface may have failed first: say so, it is
            // usually the same cause seen earlier.
            if (measurements.heights_fallback.empty()) throw;
            throw solve::FitError(std::string(e.what()) + "; measuring, " +
                                  measurements.heights_fallback);
        }
        s.after = s.fit.correction.after;
    } else {
        // The fit still runs for its report (what the data determine), but sends nothing.
        s.fit.fitted = solve::estimate_delta_geometry(machine, measurements.features, heights);
        s.fit.correction = solve::design_delta_correction(machine, s.fit.fitted);
        std::vector<solve::BarMeasurement> bars;
        for (const auto& b : measurements.bars)
            bars.push_back({b.commanded_from_mm, b.commanded_to_mm, b.measured_mm});
        s.classic_bars = bars.size();
        s.after = s.fit.fitted.before;
        s.after.diagonal_rod_mm = solve::classic_rod_length_mm(*machine.delta, bars);
        s.fit.parameters = solve::report_parameters(s.fit.fitted, s.after);
        solve::check_correction_bounds(s.fit.fitted.before, s.after, machine.delta_limits);
    }
    s.commands = models::firmware_commands(s.firmware, s.after);
    return s;
}

DeltaPassStep next_delta_pass_step(const DeltaSolution& solution, int pass,
                                   const DeltaPassLimits& limits) {
    if (pass < 1 || limits.max_passes < 1)
        throw SolveError("passes count from 1 and at least one is allowed");
    const auto& c = solution.fit.correction;
    // The classic method corrects the rod alone and says nothing of the bed: one pass.
    if (solution.method != DeltaMethod::fit) return DeltaPassStep::apply;
    // A level bed at the first pass: its first layer measured the printer well, one pass does;
    // so does a probe, which measured the gap itself.
    if (pass == 1 && (solution.heights_from_probe ||
                      c.predicted_height_range_now_mm <= limits.gap_range_limit_mm))
        return DeltaPassStep::apply;
    // Passes go on until a correction would change less than the tolerance.
    if (pass > 1 && c.predicted_xy_change_mm <= limits.holds_within_mm &&
        c.predicted_height_change_mm <= limits.holds_within_mm)
        return DeltaPassStep::holds;
    return pass < limits.max_passes ? DeltaPassStep::apply_then_measure_again
                                    : DeltaPassStep::apply_and_stop_out_of_passes;
}

const char* pass_step_name(DeltaPassStep step) {
    switch (step) {
        case DeltaPassStep::apply:
            return "sent";
        case DeltaPassStep::apply_then_measure_again:
            return "sent, measured again";
        case DeltaPassStep::holds:
            return "holds, nothing sent";
        case DeltaPassStep::apply_and_stop_out_of_passes:
            return "sent, no pass left";
    }
    return "?";
}

std::string describe_delta_pass(const DeltaSolution& solution, int pass, DeltaPassStep step,
                                const DeltaPassLimits& limits) {
    const auto& c = solution.fit.correction;
    const std::string against =
        solution.heights_from_probe
            ? "probed"
            : "limit " + number_text("%.3f", limits.gap_range_limit_mm) + " mm";
    char found[240];
    std::snprintf(found, sizeof found,
                  "pass %d: the nozzle's gap varied by %.3f mm over the bed (%s); the correction "
                  "moves the nozzle by up to %.4f mm in XY, %.4f mm in height",
                  pass, c.predicted_height_range_now_mm, against.c_str(), c.predicted_xy_change_mm,
                  c.predicted_height_change_mm);
    switch (step) {
        case DeltaPassStep::apply:
            return std::string(found) + ": sent, the printer then printed the target to verify";
        case DeltaPassStep::apply_then_measure_again:
            return std::string(found) +
                   ": sent, and the target printed again on the levelled bed is the next pass";
        case DeltaPassStep::holds:
            return std::string(found) + ": within " + number_text("%.3f", limits.holds_within_mm) +
                   " mm, nothing sent: the printer holds";
        case DeltaPassStep::apply_and_stop_out_of_passes:
            return std::string(found) + ": sent, and no pass is left (" +
                   std::to_string(limits.max_passes) +
                   " allowed) to see whether it holds; if a later cycle finds the same, check "
                   "that the bed is flat and firmly mounted";
    }
    return found;
}

}  // namespace calbox::modes
