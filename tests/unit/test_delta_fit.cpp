// The delta fit on synthetic measurements made by the twin's own reference kinematics (never by
// the code under test), judged in the twin's truth.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <sstream>

#include "board/sim/delta_judge.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/scenario.hpp"
#include "core/models/delta.hpp"
#include "core/models/delta_commands.hpp"
#include "core/solve/delta_fit.hpp"
#include "core/geometry/placement.hpp"

using namespace calbox;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Case {
    sim::DeltaParams truth, firmware;
    std::vector<solve::FeatureMeasurement> features;
    models::MachineFile machine;
    std::unique_ptr<sim::DeltaTwin> twin;
};

// What a probe routine (Marlin's G33, RepRapFirmware's G32) leaves behind: the twin's own
// routine over the centre, twelve points at 75 mm and six at 40 mm.
sim::DeltaParams levelled_firmware(const sim::DeltaParams& truth) {
    sim::DeltaTwin twin(truth, sim::DeltaParams{});
    twin.level_by_probe(75, 40);
    return twin.firmware();
}

Case make_case(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    Case c;
    c.truth.diagonal_rod_mm = 250 + 1.5 * u(rng);
    for (auto& t : c.truth.diagonal_rod_trim_mm) t = u(rng);
    c.truth.radius_mm = 140 + u(rng);
    for (auto& a : c.truth.tower_angle_trim_deg) a = 0.5 * u(rng);
    for (auto& e : c.truth.endstop_offset_mm) e = -0.15 * (1 + u(rng));
    c.firmware = levelled_firmware(c.truth);
    c.twin = std::make_unique<sim::DeltaTwin>(c.truth, c.firmware);
    c.twin->home();
    c.machine.kind = "delta";
    c.machine.bed_radius_mm = 85;
    c.machine.delta = sim::machine_settings(c.twin->firmware());
    // 150 features over the bed, seen with the artifact turned and shifted on the bed.
    const double phi = 0.03 * u(rng), tx = 3 * u(rng), ty = 3 * u(rng);
    std::normal_distribution<double> noise(0, 0.01);
    for (int k = 0; c.features.size() < 150; ++k) {
        const double r = 78 * std::sqrt((k % 150 + 0.5) / 150.0), a = k * 2.399963;  // a sunflower
        const sim::Vec3 commanded{r * std::cos(a), r * std::sin(a), 0.2};
        const sim::Vec3 actual = c.twin->actual_position_mm(commanded);
        solve::FeatureMeasurement f;
        f.id = "f";  // appended: GCC 12's -O3 -Wrestrict misfires on "f" + string
        f.id += std::to_string(k);
        f.commanded_mm = {commanded.x, commanded.y, commanded.z};
        f.measured_mm = {std::cos(phi) * actual.x - std::sin(phi) * actual.y + tx + noise(rng),
                         std::sin(phi) * actual.x + std::cos(phi) * actual.y + ty + noise(rng)};
        c.features.push_back(f);
    }
    return c;
}

}  // namespace

namespace {
// One geometry off in every parameter, for the conversions and the firmware lines.
models::DeltaGeometry sample_geometry() {
    models::DeltaGeometry g;
    g.diagonal_rod_mm = 250.7;
    g.diagonal_rod_trim_mm = {0.3, -0.5, 0.2};
    g.radius_mm = 139.2;
    g.tower_angle_trim_deg = {0.25, -0.4, 0.15};
    g.endstop_offset_mm = {-0.3, 0, -0.12};
    g.height_mm = 301.4;
    return g;
}
}  // namespace

TEST_GROUP(DeltaKinematics){};

TEST(DeltaKinematics, agrees_with_the_twins_reference_and_marlin_by_hand) {
    // Tower A at 210 degrees, radius 140: sqrt(250^2 - 131.2436^2 - 90^2) + 5 = 197.8085290370.
    const auto h = models::carriage_heights_mm(models::DeltaGeometry{}, {10, 20, 5});
    DOUBLES_EQUAL(197.8085290370, h[0], 1e-9);
    DOUBLES_EQUAL(209.9996856841, h[1], 1e-9);
    DOUBLES_EQUAL(224.0890230021, h[2], 1e-9);
    sim::DeltaParams t;
    t.diagonal_rod_mm = 251;
    t.diagonal_rod_trim_mm = {0.3, -0.2, 0.1};
    t.tower_angle_trim_deg = {0.2, -0.1, 0.3};
    t.endstop_offset_mm = {-0.2, 0, -0.1};
    t.radius_mm = 139.4;
    sim::DeltaTwin twin(t, sim::DeltaParams{});
    twin.home();
    for (const sim::Vec3 q : {sim::Vec3{0, 0, 0}, sim::Vec3{50, -40, 0.2}, sim::Vec3{-70, 20, 3}}) {
        const sim::Vec3 expected = twin.actual_position_mm(q);
        const auto got = models::actual_position_mm(sim::machine_settings(t),
                                                    models::DeltaGeometry{}, {q.x, q.y, q.z});
        DOUBLES_EQUAL(expected.x, got.x, 1e-9);
        DOUBLES_EQUAL(expected.y, got.y, 1e-9);
        DOUBLES_EQUAL(expected.z, got.z, 1e-9);
    }
}

TEST(DeltaKinematics, conventions_round_trip_to_a_nanometre) {
    const models::DeltaGeometry g = sample_geometry();
    const auto check = [&](const models::DeltaGeometry& back) {
        DOUBLES_EQUAL(g.diagonal_rod_mm, back.diagonal_rod_mm, 1e-9);
        DOUBLES_EQUAL(g.radius_mm, back.radius_mm, 1e-9);
        DOUBLES_EQUAL(g.height_mm, back.height_mm, 1e-9);
        for (std::size_t i = 0; i < 3; ++i) {
            DOUBLES_EQUAL(g.diagonal_rod_trim_mm[i], back.diagonal_rod_trim_mm[i], 1e-9);
            DOUBLES_EQUAL(g.tower_angle_trim_deg[i], back.tower_angle_trim_deg[i], 1e-9);
            DOUBLES_EQUAL(g.endstop_offset_mm[i], back.endstop_offset_mm[i], 1e-9);
        }
    };
    check(models::from_rrf(models::to_rrf(g)));
    check(models::from_klipper(models::to_klipper(g)));
    // Klipper's trigger heights: H - offset (tower A's switch 0.3 mm higher than its home).
    DOUBLES_EQUAL(301.7, models::to_klipper(g).position_endstop_mm[0], 1e-12);
    DOUBLES_EQUAL(210.25, models::to_klipper(g).angle_deg[0], 1e-12);
}

TEST(DeltaKinematics, firmware_lines_for_one_geometry_match_hand_worked_values) {
    const models::DeltaGeometry g = sample_geometry();
    const auto marlin = models::marlin_commands(g);
    STRCMP_EQUAL("M665 L250.700 R139.200 H301.400 X0.250 Y-0.400 Z0.150 A0.300 B-0.500 C0.200",
                 marlin[0].c_str());
    STRCMP_EQUAL("M666 X-0.300 Y0.000 Z-0.120", marlin[1].c_str());
    STRCMP_EQUAL("M500", marlin[2].c_str());
    // RRF: diagonals 251.0 250.2 250.9, angles relative to Z's 0.15, endstops negated.
    const auto rrf = models::rrf_commands(g);
    STRCMP_EQUAL("M665 L251.000:250.200:250.900 R139.200 H301.400 X0.100 Y-0.550 Z0.000",
                 rrf[0].c_str());
    STRCMP_EQUAL("M666 X0.300 Y0.000 Z0.120", rrf[1].c_str());
    const auto klipper = models::klipper_snippet(g);
    STRCMP_EQUAL("delta_radius: 139.200", klipper[1].c_str());
    STRCMP_EQUAL("arm_length: 251.000", klipper[3].c_str());
    STRCMP_EQUAL("angle: 210.250", klipper[4].c_str());
    STRCMP_EQUAL("position_endstop: 301.700", klipper[5].c_str());
    STRCMP_EQUAL("angle: 329.600", klipper[8].c_str());
    STRCMP_EQUAL("position_endstop: 301.520", klipper[13].c_str());
}

TEST(DeltaKinematics, settings_reports_of_each_firmware_read_back_as_commands) {
    // Marlin 2.1's M503 delta lines, as its settings report prints them.
    const std::vector<std::string> marlin_report{
        "echo:; Endstop adjustment:", "echo:  M666 X-0.300 Y0.000 Z-0.120", "echo:; Delta config:",
        "echo:  M665 L250.700 R139.200 H301.400 S200.00 X0.250 Y-0.400 Z0.150 A0.300 B-0.500 "
        "C0.200",
        "ok"};
    const auto marlin = models::settings_from_report("marlin", marlin_report);
    CHECK_EQUAL(2U, marlin.size());
    STRCMP_EQUAL("M666 X-0.300 Y0.000 Z-0.120", marlin[0].c_str());
    const auto sample = models::marlin_commands(sample_geometry());
    STRCMP_EQUAL("", models::settings_mismatch("marlin", sample, marlin).c_str());
    // RepRapFirmware 3's replies to M665 and M666 without parameters (LinearDeltaKinematics).
    const std::vector<std::string> rrf_report{
        "Diagonals 251.000:250.200:250.900, delta radius 139.200, homed height 301.400, bed "
        "radius 85.0, X 0.100\xC2\xB0, Y -0.550\xC2\xB0, Z 0.000\xC2\xB0",
        "ok", "Endstop adjustments X0.30 Y0.00 Z0.12, tilt X0.00% Y0.00%", "ok"};
    const auto rrf = models::settings_from_report("rrf", rrf_report);
    CHECK_EQUAL(2U, rrf.size());
    STRCMP_EQUAL("M665 L251.000:250.200:250.900 R139.200 H301.400 B85.0 X0.100 Y-0.550 Z0.000",
                 rrf[0].c_str());
    STRCMP_EQUAL("M666 X0.30 Y0.00 Z0.12 A0.00 B0.00", rrf[1].c_str());
    STRCMP_EQUAL(
        "", models::settings_mismatch("rrf", models::rrf_commands(sample_geometry()), rrf).c_str());
    // One rod length printed as "Diagonal": every tower's.
    const auto one_rod = models::settings_from_report(
        "rrf", {"Diagonal 250.000, delta radius 140.000, homed height 300.000, bed radius 85.0, "
                "X 0.000\xC2\xB0, Y 0.000\xC2\xB0, Z 0.000\xC2\xB0"});
    STRCMP_EQUAL("M665 L250.000 R140.000 H300.000 B85.0 X0.000 Y0.000 Z0.000", one_rod[0].c_str());
    STRCMP_EQUAL(
        "", models::settings_mismatch("rrf", {"M665 L250.000:250.000:250.000"}, one_rod).c_str());
    // A difference beyond the printed precision is named; within it, it is not.
    STRCMP_EQUAL("M665 L sent 250.904, the printer reports 250.900",
                 models::settings_mismatch("rrf", {"M665 L251.000:250.200:250.904"}, rrf).c_str());
    STRCMP_EQUAL("", models::settings_mismatch("rrf", {"M666 X0.309"}, rrf).c_str());
    STRCMP_EQUAL("M666 Y sent 0.020, the printer reports 0.000",
                 models::settings_mismatch("rrf", {"M666 X0.3 Y0.02"}, rrf).c_str());
    STRCMP_EQUAL("M665 R sent 139.202, the printer reports 139.200",
                 models::settings_mismatch("marlin", {"M665 R139.202"}, marlin).c_str());
    STRCMP_EQUAL("the printer does not report M666",
                 models::settings_mismatch("marlin", {"M666 X0"}, {"M665 L250"}).c_str());
    CHECK(models::settings_from_report("rrf", {"ok"}).empty());
    // Either report gives back the geometry that was sent, in gauge, to the printed digits.
    const models::DeltaGeometry want = models::in_gauge(sample_geometry());
    for (const auto& read : {models::geometry_from_settings("marlin", marlin),
                             models::geometry_from_settings("rrf", rrf)}) {
        DOUBLES_EQUAL(want.diagonal_rod_mm, read.diagonal_rod_mm, 1e-9);
        DOUBLES_EQUAL(want.radius_mm, read.radius_mm, 1e-9);
        DOUBLES_EQUAL(want.height_mm, read.height_mm, 1e-9);
        for (std::size_t i = 0; i < 3; ++i) {
            DOUBLES_EQUAL(want.diagonal_rod_trim_mm[i], read.diagonal_rod_trim_mm[i], 1e-9);
            DOUBLES_EQUAL(want.tower_angle_trim_deg[i], read.tower_angle_trim_deg[i], 1e-9);
            DOUBLES_EQUAL(want.endstop_offset_mm[i], read.endstop_offset_mm[i], 1e-9);
        }
    }
    CHECK_THROWS(std::invalid_argument, models::geometry_from_settings("marlin", {"M665 L250"}));
    CHECK_THROWS(std::invalid_argument,
                 models::geometry_from_settings("rrf", {"M665 L250 R140", "M666 X0"}));
    CHECK_THROWS(std::invalid_argument, models::settings_query("klipper"));
    CHECK(models::settings_query("rrf") == (std::vector<std::string>{"M665", "M666"}));
}

TEST_GROUP(Placement){};

TEST(Placement, recovers_a_rotation_and_translation_worked_by_hand) {
    // Points turned 30 degrees about the origin, then moved by (3, -2).
    const std::vector<geometry::Point2> from{{0, 0}, {10, 0}, {0, 5}, {-4, 7}};
    std::vector<geometry::Point2> to;
    const double c = std::cos(kPi / 6), s = std::sin(kPi / 6);
    for (const auto& p : from) to.push_back({c * p.x - s * p.y + 3, s * p.x + c * p.y - 2});
    const auto placement = geometry::best_rigid_placement(from, to);
    DOUBLES_EQUAL(kPi / 6, placement.angle_rad, 1e-12);
    DOUBLES_EQUAL(3, placement.translation_mm.x, 1e-12);
    DOUBLES_EQUAL(-2, placement.translation_mm.y, 1e-12);
    CHECK_THROWS(std::invalid_argument, geometry::best_rigid_placement({{0, 0}}, {{1, 1}}));
}

TEST_GROUP(DeltaFit){};

TEST(DeltaFit, twenty_seeded_printers_are_recovered_within_their_uncertainty_and_corrected) {
    constexpr int kCases = 20;
    std::vector<int> within(9, 0), fitted(9, 0);
    double worst_rms = 0, worst_max = 0, worst_height = 0, classic_worst = 0, classic_sum = 0,
           before_sum = 0;
    for (int seed = 1; seed <= kCases; ++seed) {
        Case c = make_case(static_cast<unsigned>(seed));
        const auto result = solve::fit_delta(c.machine, c.features, {});
        // Truth in the same gauge; its height is what the firmware's zeroing made of it.
        models::DeltaGeometry truth = models::in_gauge(sim::machine_settings(c.truth));
        const double truth_values[9] = {truth.diagonal_rod_mm,
                                        truth.diagonal_rod_trim_mm[0],
                                        truth.diagonal_rod_trim_mm[1],
                                        truth.radius_mm,
                                        truth.tower_angle_trim_deg[0],
                                        truth.tower_angle_trim_deg[1],
                                        truth.endstop_offset_mm[0] - truth.endstop_offset_mm[2],
                                        truth.endstop_offset_mm[1] - truth.endstop_offset_mm[2],
                                        truth.height_mm};
        for (std::size_t i = 0; i < 9; ++i) {
            const auto& p = result.parameters[i];
            if (p.held) continue;
            ++fitted[i];
            if (std::abs(p.estimate - truth_values[i]) <= 3 * p.uncertainty) ++within[i];
        }
        // Both fits converged: well inside the iteration limit, the last step a sliver of a
        // parameter's scale.
        for (const auto* conv : {&result.fitted.convergence, &result.correction.convergence}) {
            CHECK_FALSE(conv->stopped_on_limit);
            CHECK(conv->iterations >= 2 && conv->iterations < 50);
            CHECK_TEXT(conv->final_step < 1e-3, std::to_string(conv->final_step).c_str());
        }
        sim::DeltaTwin fresh(c.truth, c.firmware);
        const sim::DeltaJudgement after =
            sim::judge_delta(fresh, models::marlin_commands(result.correction.after));
        before_sum += after.xy_rms_before;
        worst_rms = std::max(worst_rms, after.xy_rms);
        worst_max = std::max(worst_max, after.xy_max);
        worst_height = std::max(worst_height, after.height_change);
        // The seed paper's rod correction from three 60 mm bars along the towers, for comparison.
        std::vector<solve::BarMeasurement> bars;
        for (const double angle : {210.0, 330.0, 90.0}) {
            const sim::Vec3 end{60 * std::cos(angle * kPi / 180), 60 * std::sin(angle * kPi / 180),
                                0.2};
            const auto a = c.twin->actual_position_mm({0, 0, 0.2}),
                       b = c.twin->actual_position_mm(end);
            bars.push_back({0, 60, std::hypot(b.x - a.x, b.y - a.y)});
        }
        models::DeltaGeometry classic = *c.machine.delta;
        classic.diagonal_rod_mm = solve::classic_rod_length_mm(classic, bars);
        sim::DeltaTwin classic_twin(c.truth, c.firmware);
        const sim::DeltaJudgement classic_after =
            sim::judge_delta(classic_twin, models::marlin_commands(classic));
        classic_worst = std::max(classic_worst, classic_after.xy_rms);
        classic_sum += classic_after.xy_rms;
    }
    for (std::size_t i = 0; i < 9; ++i) {
        if (fitted[i] == 0) continue;
        CHECK_TEXT(within[i] >= 19,
                   (std::string("parameter ") + std::to_string(i) + " within 3 sigma in " +
                    std::to_string(within[i]) + " of " + std::to_string(fitted[i]))
                       .c_str());
    }
    // The common rod, the rod trims, two angle trims and two endstop offsets must be fitted.
    for (std::size_t i : {0u, 1u, 2u, 4u, 5u, 6u, 7u}) CHECK_EQUAL(kCases, fitted[i]);
    UT_PRINT(("XY RMS before " + std::to_string(before_sum / kCases) + " mm; after fit worst RMS " +
              std::to_string(worst_rms) + " mm, worst point " + std::to_string(worst_max) +
              " mm, height change " + std::to_string(worst_height) +
              " mm; classic rod correction mean RMS " + std::to_string(classic_sum / kCases) +
              " mm, worst " + std::to_string(classic_worst))
                 .c_str());
    CHECK_TEXT(worst_rms < 0.01, ("XY RMS after correction " + std::to_string(worst_rms)).c_str());
    CHECK_TEXT(worst_height <= 0.02, ("height map change " + std::to_string(worst_height)).c_str());
}

TEST(DeltaFit, with_probed_heights_an_unlevelled_printer_is_corrected_in_xy_and_z) {
    for (unsigned seed : {31u, 32u, 33u}) {
        Case c = make_case(seed);
        // The same truth under the nominal firmware, only zeroed at the centre: a dome or bowl.
        sim::DeltaTwin twin(c.truth, sim::DeltaParams{});
        twin.zero_height_at_centre();
        twin.home();
        c.machine.delta = sim::machine_settings(twin.firmware());
        for (auto& f : c.features) {
            const sim::Vec3 a =
                twin.actual_position_mm({f.commanded_mm.x, f.commanded_mm.y, f.commanded_mm.z});
            f.measured_mm = {a.x, a.y};
        }
        std::vector<solve::ProbePoint> probe;
        for (int k = 0; k < 37; ++k) {
            const double r = k == 0 ? 0 : 75.0 * ((k - 1) / 12 + 1) / 3,
                         a = k * kPi / 6 + (k - 1) / 12 * 0.3;
            const sim::Vec3 at = twin.actual_position_mm({r * std::cos(a), r * std::sin(a), 0});
            probe.push_back({r * std::cos(a), r * std::sin(a), at.z, 0.005});
        }
        const auto result = solve::fit_delta(c.machine, c.features, probe);
        CHECK(result.fitted.used_probe);
        CHECK_FALSE(result.parameters[8].held);  // the height is measured now
        const sim::DeltaJudgement before = sim::judge_delta(twin, {});
        sim::DeltaTwin fixed(c.truth, sim::DeltaParams{});
        fixed.zero_height_at_centre();
        const sim::DeltaJudgement after =
            sim::judge_delta(fixed, models::marlin_commands(result.correction.after));
        // Judge the height map after: the nozzle's height over the bed at commanded z = 0.
        fixed.home();
        double lowest = 1e9, highest = -1e9;
        for (double x = -75; x <= 75; x += 15)
            for (double y = -75; y <= 75; y += 15)
                if (std::hypot(x, y) <= 75) {
                    const double z = fixed.actual_position_mm({x, y, 0}).z;
                    lowest = std::min(lowest, z), highest = std::max(highest, z);
                }
        CHECK_TEXT(after.xy_rms < 0.01, ("XY RMS after " + std::to_string(after.xy_rms)).c_str());
        CHECK_TEXT(highest - lowest < 0.01,
                   ("height range after " + std::to_string(highest - lowest)).c_str());
        CHECK_TEXT(before.height_change == 0,
                   "judging must not move the machine before the commands");
    }
}

TEST(DeltaFit, what_a_small_artifact_cannot_determine_is_held_and_reported) {
    // Features only within 12 mm of the centre: the rod and radius barely show in XY there.
    Case c = make_case(7);
    for (auto& f : c.features) {
        const double shrink = 12.0 / 78;
        f.commanded_mm = {f.commanded_mm.x * shrink, f.commanded_mm.y * shrink, f.commanded_mm.z};
        const sim::Vec3 a =
            c.twin->actual_position_mm({f.commanded_mm.x, f.commanded_mm.y, f.commanded_mm.z});
        f.measured_mm = {a.x, a.y};
    }
    const auto result = solve::fit_delta(c.machine, c.features, {});
    int held = 0;
    for (const auto& p : result.parameters) {
        if (p.held) {
            ++held;
            // Held at the firmware's value; the height only moves by the common endstop part the
            // gauge puts into it.
            if (p.name != "height_mm") DOUBLES_EQUAL(p.before, p.estimate, 1e-9);
            DOUBLES_EQUAL(0.0, p.uncertainty, 0.0);
        } else {
            CHECK(p.uncertainty <= 0.2);
        }
    }
    CHECK(held >= 2);  // the height, and at least one of the scale parameters
}

TEST(DeltaFit, bad_input_is_refused_with_a_reason) {
    Case c = make_case(99);
    std::vector<solve::FeatureMeasurement> few(c.features.begin(), c.features.begin() + 5);
    CHECK_THROWS(solve::FitError, solve::fit_delta(c.machine, few, {}));
    auto nan = c.features;
    nan[3].measured_mm.x = std::nan("");
    CHECK_THROWS(solve::FitError, solve::fit_delta(c.machine, nan, {}));
    auto off = c.features;
    off[4].commanded_mm.x = 120;
    CHECK_THROWS(solve::FitError, solve::fit_delta(c.machine, off, {}));
    // Measurements of a printer 3 % too large: the rod change is over the limit.
    auto large = c.features;
    for (auto& f : large) f.measured_mm = {f.measured_mm.x * 1.05, f.measured_mm.y * 1.05};
    try {
        solve::fit_delta(c.machine, large, {});
        FAIL("an out-of-bounds correction was returned");
    } catch (const solve::FitError& e) {
        STRCMP_CONTAINS("refused: the measurements do not fit", e.what());
    }
    // A good measurement whose correction is beyond tight limits is refused by each bound.
    const auto refused_by = [&](const solve::DeltaFitLimits& limits, const char* why) {
        try {
            solve::fit_delta(c.machine, c.features, {}, limits);
            FAIL("an out-of-bounds correction was returned");
        } catch (const solve::FitError& e) {
            STRCMP_CONTAINS(why, e.what());
        }
    };
    refused_by({1e-5, 3.0, 0.02, 3.0}, "refused: the rod length would change");
    refused_by({0.02, 1e-4, 0.02, 3.0}, "refused: a tower angle trim");
    refused_by({0.02, 3.0, 1e-6, 3.0}, "refused: the radius would change");
    CHECK_EQUAL(9u, solve::fit_delta(c.machine, c.features, {}).parameters.size());
    // A machine file whose rods cannot reach the measured corners: a fit error that says so,
    // not the kinematics' own exception.
    auto short_rods = c.machine;
    short_rods.delta->diagonal_rod_mm = 150;
    try {
        solve::fit_delta(short_rods, c.features, {});
        FAIL("a fit started where the nozzle cannot go");
    } catch (const solve::FitError& e) {
        STRCMP_CONTAINS("the fit cannot go on: at the starting geometry", e.what());
    }
}

TEST(DeltaFit, the_classic_method_answers_within_its_search_and_refuses_beyond_it) {
    models::DeltaGeometry firmware;
    firmware.diagonal_rod_mm = 250;
    firmware.radius_mm = 140;
    // Worked by hand: a bar as long as it was commanded is what the firmware's own rod gives
    // (the paper's L = L* at d = d0).
    DOUBLES_EQUAL(250.0, solve::classic_rod_length_mm(firmware, {{0, 60, 60.0}}), 1e-6);
    // Worked by hand from the paper's equations: rods of 200 and 300 mm make a 60 mm bar 38.891
    // and 85.789 mm long, so one read as 90 mm is beyond the search.
    try {
        solve::classic_rod_length_mm(firmware, {{0, 60, 60.0}, {0, 60, 90.0}});
        FAIL("an end of the search was returned");
    } catch (const solve::FitError& e) {
        STRCMP_CONTAINS(
            "a bar measured 90.000 mm (commanded from 0.0 to 60.0 mm) is not what any "
            "rod from 200.0 to 300.0 mm gives (38.891 to 85.789 mm)",
            e.what());
    }
    CHECK_THROWS(solve::FitError, solve::classic_rod_length_mm(firmware, {{0, 60, std::nan("")}}));
}
