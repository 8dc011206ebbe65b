// The delta mode's files, written and read in one place: each schema survives a round trip
// field for field, and the solve's policy refuses what it must before fitting anything.
#include <CppUTest/TestHarness.h>

#include "core/models/machine_file.hpp"
#include "core/modes/delta_records.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;

namespace {

modes::DeltaMeasurementsRecord sample_measurements() {
    modes::DeltaMeasurementsRecord r;
    r.machine_fingerprint = "fnv1a64:0123456789abcdef";
    r.target_fingerprint = "fnv1a64:fedcba9876543210";
    r.photos = {"a.png", "b.png"};
    r.bed_scale = 0.9993;
    r.heights_from_fit = true;
    r.heights_fallback = "the surface fit failed (why)";
    solve::FeatureMeasurement f;
    f.id = "m3c1";
    f.commanded_mm = {12.5, -30.25, 0.2};
    f.measured_mm = {12.61, -30.19};
    f.sigma_mm = 0.004;
    f.seen_at_height_mm = 0.21;
    f.shift_per_height = {0.03, -0.07};
    f.refined = false;
    r.features = {f};
    modes::BarLengthMeasurement b;
    b.tower = 'B';
    b.commanded_from_mm = 20;
    b.commanded_to_mm = 70;
    b.commanded_mm = 50;
    b.measured_mm = 50.12;
    b.sigma_mm = 0.003;
    b.surface_height_mm = 0.4;
    r.bars = {b};
    return r;
}

}  // namespace

TEST_GROUP(DeltaRecords){};

TEST(DeltaRecords, measurements_round_trip_field_for_field) {
    const auto r = sample_measurements();
    const std::string text = modes::measurements_to_json(r);
    STRCMP_CONTAINS("\"schema\": \"calbox.measurements/1\"", text.c_str());
    const auto back = modes::measurements_from_json(text, "m.json");
    STRCMP_EQUAL(r.machine_fingerprint.c_str(), back.machine_fingerprint.c_str());
    STRCMP_EQUAL(r.target_fingerprint.c_str(), back.target_fingerprint.c_str());
    CHECK(r.photos == back.photos);
    DOUBLES_EQUAL(0.9993, back.bed_scale, 0);
    CHECK(back.heights_from_fit);
    STRCMP_EQUAL("the surface fit failed (why)", back.heights_fallback.c_str());
    CHECK_EQUAL(1u, back.features.size());
    const auto& f = back.features[0];
    STRCMP_EQUAL("m3c1", f.id.c_str());
    DOUBLES_EQUAL(-30.25, f.commanded_mm.y, 0);
    DOUBLES_EQUAL(0.2, f.commanded_mm.z, 0);
    DOUBLES_EQUAL(12.61, f.measured_mm.x, 0);
    DOUBLES_EQUAL(0.004, f.sigma_mm, 0);
    DOUBLES_EQUAL(0.21, f.seen_at_height_mm, 0);
    DOUBLES_EQUAL(-0.07, f.shift_per_height.y, 0);
    CHECK_FALSE(f.refined);
    const auto& b = back.bars.at(0);
    CHECK_EQUAL('B', b.tower);
    DOUBLES_EQUAL(20, b.commanded_from_mm, 0);
    DOUBLES_EQUAL(70, b.commanded_to_mm, 0);
    DOUBLES_EQUAL(50.12, b.measured_mm, 0);
    DOUBLES_EQUAL(0.4, b.surface_height_mm, 0);
    STRCMP_EQUAL(text.c_str(), modes::measurements_to_json(back).c_str());
}

TEST(DeltaRecords, a_result_round_trips_and_keeps_what_was_held) {
    modes::DeltaSolution s;
    s.method = modes::DeltaMethod::fit;
    s.firmware = "rrf";
    s.machine_fingerprint = "fnv1a64:0123456789abcdef";
    auto& fitted = s.fit.fitted;
    fitted.estimate.diagonal_rod_mm = 251.25;
    fitted.estimate.tower_angle_trim_deg = {0.25, -0.125, -0.125};
    fitted.singular_values = {3.5, 1.25, 0.5};
    fitted.condition_number = 7;
    fitted.fit_rms_mm = 0.0031;
    fitted.placement = {0.01, {1.5, -2.5}};
    fitted.held[8] = true;  // the height, without a probe
    fitted.uncertainty[0] = 0.004;
    s.fit.correction.predicted_xy_rms_mm = 0.002;
    s.fit.correction.predicted_xy_max_mm = 0.005;
    s.fit.correction.predicted_xy_change_mm = 0.125;
    s.fit.correction.predicted_height_range_now_mm = 0.3;
    s.fit.correction.levels_bed = true;
    fitted.convergence = {7, 2.5e-6, "a step that no longer lowers the residual", false};
    s.fit.correction.convergence = {100, 0.25, "the iteration limit", true};
    s.after = fitted.estimate;
    s.after.radius_mm = 140.5;
    s.fit.correction.after = s.after;
    s.fit.parameters = solve::report_parameters(fitted, s.after);
    s.commands = {"M665 L251.250:251.250:251.250 R140.500", "M500"};
    s.heights_from_probe = true;
    const std::string text = modes::result_to_json(s);
    STRCMP_CONTAINS("\"heights_from\": \"probe\"", text.c_str());
    STRCMP_CONTAINS("\"height_mm\": null", text.c_str());
    const auto back = modes::result_from_json(text, "r.json");
    CHECK(back.method == modes::DeltaMethod::fit);
    STRCMP_EQUAL("rrf", back.firmware.c_str());
    DOUBLES_EQUAL(140.5, back.after.radius_mm, 0);
    DOUBLES_EQUAL(0.125, back.fit.correction.predicted_xy_change_mm, 0);
    DOUBLES_EQUAL(251.25, back.fit.fitted.estimate.diagonal_rod_mm, 0);
    CHECK(back.fit.fitted.held[8]);
    CHECK_FALSE(back.fit.fitted.held[0]);
    DOUBLES_EQUAL(0.004, back.fit.fitted.uncertainty[0], 0);
    DOUBLES_EQUAL(-2.5, back.fit.fitted.placement.translation_mm.y, 1e-12);
    CHECK(back.commands == s.commands);
    CHECK(back.heights_from_probe);
    CHECK_EQUAL(7, back.fit.fitted.convergence.iterations);
    DOUBLES_EQUAL(2.5e-6, back.fit.fitted.convergence.final_step, 0);
    CHECK_FALSE(back.fit.fitted.convergence.stopped_on_limit);
    CHECK(back.fit.correction.convergence.stopped_on_limit);
    STRCMP_EQUAL("the iteration limit", back.fit.correction.convergence.stopped_on.c_str());
    STRCMP_EQUAL(text.c_str(), modes::result_to_json(back).c_str());
}

TEST(DeltaRecords, the_wrong_schema_or_broken_text_is_refused_with_its_name) {
    try {
        modes::measurements_from_json(R"({"schema": "calbox.delta-result/1"})", "x.json");
        FAIL("accepted a result as measurements");
    } catch (const modes::RecordError& e) {
        STRCMP_EQUAL("x.json: not a measurements file (schema calbox.measurements/1)", e.what());
    }
    CHECK_THROWS(modes::RecordError, modes::result_from_json("{", "r.json"));
    CHECK_THROWS(modes::RecordError,
                 modes::measurements_from_json(R"({"schema": "calbox.measurements/1"})", "m"));
}

TEST(DeltaRecords, the_solve_refuses_another_machine_and_an_unknown_firmware_before_fitting) {
    const auto machine = models::parse_machine_file(test::kDeltaMachineToml, "machine");
    auto r = sample_measurements();
    try {
        modes::solve_delta(machine, r, {});
        FAIL("solved another machine's measurements");
    } catch (const modes::SolveError& e) {
        STRCMP_CONTAINS("made for another machine", e.what());
    }
    r.machine_fingerprint = models::fingerprint(machine);
    modes::DeltaSolveOptions options;
    options.firmware = "grbl";
    CHECK_THROWS(modes::SolveError, modes::solve_delta(machine, r, {}, options));
    CHECK_THROWS(modes::SolveError, modes::parse_method("best"));
    // With the policy passed, the fit itself refuses one feature (it needs twelve).
    CHECK_THROWS(solve::FitError, modes::solve_delta(machine, r, {}));
}

// Calibrating until the printer holds (issue "Delta mode 3"): what follows each pass, from the
// gap the fit found and the change its correction makes, against the default limits (0.1 mm of
// gap, 0.01 mm of change, three passes).
namespace {
modes::DeltaSolution pass_solution(double gap_mm, double xy_change_mm, double height_change_mm) {
    modes::DeltaSolution s;
    s.fit.correction.predicted_height_range_now_mm = gap_mm;
    s.fit.correction.predicted_xy_change_mm = xy_change_mm;
    s.fit.correction.predicted_height_change_mm = height_change_mm;
    return s;
}
}  // namespace

TEST_GROUP(DeltaPasses){};

TEST(DeltaPasses, a_bed_whose_gap_varies_past_the_limit_is_levelled_and_measured_again) {
    using Step = modes::DeltaPassStep;
    // Pass 1 always sends: a level bed ends the cycle, an uneven one asks for another pass.
    CHECK(Step::apply == modes::next_delta_pass_step(pass_solution(0.1, 0.5, 0.2), 1));
    CHECK(Step::apply_then_measure_again ==
          modes::next_delta_pass_step(pass_solution(0.101, 0.001, 0.001), 1));
    // A later pass whose correction moves the nozzle 0.01 mm or less: the printer holds, nothing
    // is sent (a bed the geometry cannot level further holds too: the change says so). One more
    // micrometre, in XY or in height, and it is sent and measured again, while passes are left.
    CHECK(Step::holds == modes::next_delta_pass_step(pass_solution(0.05, 0.01, 0.01), 2));
    CHECK(Step::holds == modes::next_delta_pass_step(pass_solution(0.3, 0.002, 0.002), 3));
    CHECK(Step::apply_then_measure_again ==
          modes::next_delta_pass_step(pass_solution(0.05, 0.011, 0.0), 2));
    CHECK(Step::apply_then_measure_again ==
          modes::next_delta_pass_step(pass_solution(0.02, 0.0, 0.011), 2));
    // The last pass allowed sends what it found and the cycle stops.
    CHECK(Step::apply_and_stop_out_of_passes ==
          modes::next_delta_pass_step(pass_solution(0.02, 0.0, 0.011), 3));
    modes::DeltaPassLimits one;
    one.max_passes = 1;
    CHECK(Step::apply_and_stop_out_of_passes ==
          modes::next_delta_pass_step(pass_solution(0.3, 0.2, 0.2), 1, one));
    // The classic method corrects the rod alone: one pass, whatever the bed.
    auto classic = pass_solution(0.4, 0.3, 0.3);
    classic.method = modes::DeltaMethod::classic;
    CHECK(Step::apply == modes::next_delta_pass_step(classic, 1));
    CHECK_THROWS(modes::SolveError, modes::next_delta_pass_step(classic, 0));
    // A probe measured the gap itself: its pass is the only one, however uneven the bed.
    auto probed = pass_solution(0.4, 0.3, 0.3);
    probed.heights_from_probe = true;
    CHECK(Step::apply == modes::next_delta_pass_step(probed, 1));
    STRCMP_CONTAINS("pass 1: the nozzle's gap varied by 0.400 mm over the bed (probed); ",
                    modes::describe_delta_pass(probed, 1, Step::apply).c_str());
}

TEST(DeltaPasses, each_pass_says_what_it_found_and_what_follows) {
    using Step = modes::DeltaPassStep;
    STRCMP_EQUAL(
        "pass 2: the nozzle's gap varied by 0.004 mm over the bed (limit 0.100 mm); the "
        "correction moves the nozzle by up to 0.0030 mm in XY, 0.0020 mm in height: within "
        "0.010 mm, nothing sent: the printer holds",
        modes::describe_delta_pass(pass_solution(0.004, 0.003, 0.002), 2, Step::holds).c_str());
    const auto last = modes::describe_delta_pass(pass_solution(0.25, 0.03, 0.2), 3,
                                                 Step::apply_and_stop_out_of_passes);
    STRCMP_CONTAINS("pass 3: the nozzle's gap varied by 0.250 mm", last.c_str());
    STRCMP_CONTAINS("no pass is left (3 allowed) to see whether it holds", last.c_str());
    STRCMP_CONTAINS("check that the bed is flat and firmly mounted", last.c_str());
    STRCMP_CONTAINS(
        "sent, and the target printed again on the levelled bed is the next pass",
        modes::describe_delta_pass(pass_solution(0.25, 0.1, 0.2), 1, Step::apply_then_measure_again)
            .c_str());
}
