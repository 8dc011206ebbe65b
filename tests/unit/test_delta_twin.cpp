// The twin's delta printer against values worked out by hand from the formulas of Marlin's
// delta.cpp (towers at 210/330/90 degrees; carriage = z + sqrt(rod^2 - dx^2 - dy^2)) and an
// independent Newton solution of the three rod-length equations (tests/reference/delta_hand.py).
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <sstream>

#include "board/sim/delta_reference.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"

using namespace calbox::sim;

namespace {
DeltaParams kossel() {
    return DeltaParams{};
}  // rod 250, radius 140, height 300, no trims

JobResult run_job(MachineTwin& machine, const std::string& job) {
    GcodeRunner runner(machine, ToolSettings{});
    std::istringstream in(job);
    runner.run(in);
    return runner.result();
}

// A 40 mm square outline at z = 0.2 around the bed centre, one line per side.
const char* kSquareJob =
    "G28\nG92 E0\nG0 Z5\nG0 X-20 Y-20\nG0 Z0.2\n"
    "G1 X20 Y-20 E2\nG1 X20 Y20 E4\nG1 X-20 Y20 E6\nG1 X-20 Y-20 E8\n";
}  // namespace

TEST_GROUP(DeltaReference){};

TEST(DeltaReference, inverse_kinematics_matches_marlin_formula_by_hand) {
    // Tower A at (140 cos 210, 140 sin 210) = (-121.2436, -70): dx = -131.2436, dy = -90,
    // sqrt(62500 - 17224.88 - 8100) + 5 = 197.8085290370.
    const auto h = reference_carriage_heights_mm(kossel(), {10, 20, 5});
    DOUBLES_EQUAL(197.8085290370, h[0], 1e-9);
    DOUBLES_EQUAL(209.9996856841, h[1], 1e-9);
    DOUBLES_EQUAL(224.0890230021, h[2], 1e-9);
    const auto centre = reference_carriage_heights_mm(kossel(), {0, 0, 0});
    DOUBLES_EQUAL(207.1231517721, centre[0], 1e-9);  // sqrt(250^2 - 140^2)
}

TEST(DeltaReference, forward_kinematics_inverts_inverse_with_trims) {
    DeltaParams p = kossel();
    p.diagonal_rod_trim_mm = {0.4, -0.3, -0.1};
    p.tower_angle_trim_deg = {0.3, -0.2, -0.1};
    for (const Vec3 q : {Vec3{0, 0, 0}, Vec3{60, -30, 2}, Vec3{-70, 10, 0.2}, Vec3{5, 80, 10}}) {
        const Vec3 back = reference_effector_position_mm(p, reference_carriage_heights_mm(p, q));
        DOUBLES_EQUAL(q.x, back.x, 1e-9);
        DOUBLES_EQUAL(q.y, back.y, 1e-9);
        DOUBLES_EQUAL(q.z, back.z, 1e-9);
    }
}

TEST(DeltaReference, tower_angle_trims_rotate_towers_counter_clockwise) {
    DeltaParams p = kossel();
    p.tower_angle_trim_deg = {0, 0, 1.0};
    const auto t = towers_of(p);
    DOUBLES_EQUAL(140 * std::cos(91 * kPi / 180), t[2].x_mm, 1e-12);
    DOUBLES_EQUAL(140 * std::sin(91 * kPi / 180), t[2].y_mm, 1e-12);
}

TEST(DeltaReference, unreachable_point_is_refused) {
    CHECK_THROWS(OutOfReach, reference_carriage_heights_mm(kossel(), {300, 0, 0}));
}

TEST_GROUP(DeltaTwin){};

TEST(DeltaTwin, exact_firmware_prints_where_commanded) {
    DeltaTwin twin(kossel(), kossel());
    const auto result = run_job(twin, kSquareJob);
    CHECK(result.strokes.size() >= 4 * 80);
    for (const auto& s : result.strokes) {
        DOUBLES_EQUAL(s.commanded_b_mm.x, s.b_mm.x, 1e-9);
        DOUBLES_EQUAL(s.commanded_b_mm.y, s.b_mm.y, 1e-9);
        DOUBLES_EQUAL(0.2, s.b_mm.z, 1e-9);
    }
}

TEST(DeltaTwin, stroke_width_follows_extruded_volume) {
    DeltaTwin twin(kossel(), kossel());
    const auto result = run_job(twin, kSquareJob);
    // 2 mm of 1.75 mm filament over a 40 mm side at 0.2 mm layers:
    // pi * 1.75^2 / 4 * 2 / (40 * 0.2) = 0.601320 mm.
    DOUBLES_EQUAL(0.6013204, result.strokes.front().width_mm, 1e-6);
}

TEST(DeltaTwin, longer_true_rods_print_the_square_where_worked_out_by_hand) {
    DeltaParams truth = kossel();
    truth.diagonal_rod_mm = 251.0;
    DeltaTwin twin(truth, kossel());
    twin.zero_height_at_centre();
    // Commanded point -> true position, solved by hand (tests/reference/delta_hand.py).
    struct Case {
        double cx, cy, x, y, z;
    };
    const Case cases[] = {
        {20, 0, 20.116758375, 0.001927803, 0.204364044},
        {0, 20, 0.000000000, 20.114839225, 0.204220810},
        {0, -20, 0.000000000, -20.118677554, 0.204507275},
        {20, 20, 20.120978449, 20.117065269, 0.209056278},
        {-20, -20, -20.113186803, -20.117099814, 0.208477401},
    };
    twin.home();
    for (const auto& c : cases) {
        const Vec3 p = twin.actual_position_mm({c.cx, c.cy, 0.2});
        DOUBLES_EQUAL(c.x, p.x, 2e-9);
        DOUBLES_EQUAL(c.y, p.y, 2e-9);
        DOUBLES_EQUAL(c.z, p.z, 2e-9);
    }
    // The printed square's corners land at those points.
    const auto result = run_job(twin, kSquareJob);
    const auto& first_side_end = result.strokes.at(result.strokes.size() / 4 - 1).b_mm;
    DOUBLES_EQUAL(20.113186803, first_side_end.x, 2e-9);
    DOUBLES_EQUAL(-20.117099814, first_side_end.y, 2e-9);
}

TEST(DeltaTwin, m665_changes_geometry_as_marlin_does_and_m503_reports_it) {
    DeltaParams truth = kossel();
    truth.diagonal_rod_mm = 251.0;
    truth.diagonal_rod_trim_mm = {0.2, -0.1, -0.1};
    truth.tower_angle_trim_deg = {0.2, -0.3, 0.1};
    truth.radius_mm = 140.5;
    DeltaTwin twin(truth, kossel());
    twin.home();
    CHECK(std::abs(twin.actual_position_mm({40, 0, 0}).x - 40) > 0.1);
    // Telling the firmware the true geometry makes it exact everywhere.
    const auto result = run_job(twin,
                                "M665 L251 R140.5 X0.2 Y-0.3 Z0.1 A0.2 B-0.1 C-0.1\n"
                                "M503\nG28\n");
    CHECK(twin.homed());
    for (const Vec3 q : {Vec3{40, 0, 0}, Vec3{-30, 50, 1}, Vec3{0, -70, 0.2}}) {
        const Vec3 p = twin.actual_position_mm(q);
        DOUBLES_EQUAL(q.x, p.x, 1e-9);
        DOUBLES_EQUAL(q.y, p.y, 1e-9);
        DOUBLES_EQUAL(q.z, p.z, 1e-9);
    }
    bool reported = false;
    for (const auto& r : result.replies) {
        if (r ==
            "echo:  M665 L251.000 R140.500 H300.000 X0.200 Y-0.300 Z0.100 A0.200 B-0.100 C-0.100")
            reported = true;
    }
    CHECK(reported);
}

TEST(DeltaTwin, m665_unhomes_the_machine_like_marlin) {
    DeltaTwin twin(kossel(), kossel());
    GcodeRunner runner(twin, ToolSettings{});
    runner.run_line("G28");
    runner.run_line("M665 L251");
    CHECK_THROWS(JobError, runner.run_line("G1 X1"));
}

TEST(DeltaTwin, m666_offsets_lower_one_carriage_after_homing) {
    DeltaParams truth = kossel();
    truth.endstop_offset_mm = {-0.3, 0, 0};  // tower A's switch triggers 0.3 mm high
    DeltaTwin twin(truth, kossel());
    twin.home();
    const double before = twin.actual_position_mm({0, 0, 0}).z;
    // Tower A's carriage sits 0.3 mm too high: the nozzle rises and tilts towards A.
    CHECK(before > 0.05);
    const auto result = run_job(twin, "M666 X-0.3\nG28\nM666 X0.5\nM503\n");
    const Vec3 p = twin.actual_position_mm({0, 0, 0});
    DOUBLES_EQUAL(0.0, p.x, 1e-9);
    DOUBLES_EQUAL(0.0, p.z, 1e-9);
    // A positive offset is refused, as Marlin refuses it, and the old one stays.
    bool refused = false, reported = false;
    for (const auto& r : result.replies) {
        refused |= r == "?M666 offsets must be <= 0";
        reported |= r == "echo:  M666 X-0.300 Y0.000 Z0.000";
    }
    CHECK(refused);
    CHECK(reported);
}

TEST(DeltaTwin, reprapfirmware_dialect_sets_per_tower_rods_and_reports_as_rrf_prints) {
    DeltaParams truth = kossel();
    truth.diagonal_rod_mm = 251.0;
    truth.diagonal_rod_trim_mm = {0.2, -0.1, -0.1};
    truth.tower_angle_trim_deg = {0.2, -0.3, 0.1};
    truth.radius_mm = 140.5;
    truth.endstop_offset_mm = {-0.3, 0, -0.1};  // A's switch 0.3 mm high, C's 0.1 mm
    DeltaTwin twin(truth, kossel(), DeltaDialect::rrf);
    // The true geometry in RepRapFirmware's words, worked by hand: one diagonal per tower, the
    // switches' heights as positive adjustments.
    const auto result =
        run_job(twin,
                "M665 L251.2:250.9:250.9 R140.5 X0.2 Y-0.3 Z0.1\nM666 X0.3 Z0.1\nM665\n"
                "M666\nG28\n");
    for (const Vec3 q : {Vec3{40, 0, 0}, Vec3{-30, 50, 1}, Vec3{0, -70, 0.2}, Vec3{0, 0, 0}}) {
        const Vec3 p = twin.actual_position_mm(q);
        DOUBLES_EQUAL(q.x, p.x, 1e-9);
        DOUBLES_EQUAL(q.y, p.y, 1e-9);
        DOUBLES_EQUAL(q.z, p.z, 1e-9);
    }
    bool m665 = false, m666 = false;
    for (const auto& r : result.replies) {
        m665 |= r ==
                "Diagonals 251.200:250.900:250.900, delta radius 140.500, homed height 300.000, "
                "bed radius 85.0, X 0.200\xC2\xB0, Y -0.300\xC2\xB0, Z 0.100\xC2\xB0";
        m666 |= r == "Endstop adjustments X0.30 Y0.00 Z0.10, tilt X0.00% Y0.00%";
    }
    CHECK(m665);
    CHECK(m666);
    // One diagonal for all towers; a bed tilt the twin does not model is an error reply.
    const auto more = run_job(twin, "M665 L250\nM666 A0.5\n");
    DOUBLES_EQUAL(250.0, twin.firmware().diagonal_rod_mm + twin.firmware().diagonal_rod_trim_mm[2],
                  0);
    CHECK(std::find(more.replies.begin(), more.replies.end(), "Error: the twin has no bed tilt") !=
          more.replies.end());
}

TEST(DeltaTwin, m500_stores_the_settings) {
    DeltaTwin twin(kossel(), kossel());
    run_job(twin, "M665 L252\nM500\nM665 L253\n");
    DOUBLES_EQUAL(252.0, twin.stored_firmware().diagonal_rod_mm, 0);
    DOUBLES_EQUAL(253.0, twin.firmware().diagonal_rod_mm, 0);
}

TEST(DeltaTwin, job_errors_name_the_line) {
    DeltaTwin twin(kossel(), kossel());
    GcodeRunner runner(twin, ToolSettings{});
    runner.run_line("G28");
    try {
        runner.run_line("G29");
        FAIL("unknown command accepted");
    } catch (const JobError& e) {
        STRCMP_EQUAL("line 2: unknown command G29", e.what());
    }
    try {
        runner.run_line("G1 X300 Y0 Z0");
        FAIL("unreachable point accepted");
    } catch (const JobError& e) {
        STRCMP_CONTAINS("line 3:", e.what());
        STRCMP_CONTAINS("out of reach", e.what());
    }
    DeltaTwin cold(kossel(), kossel());
    GcodeRunner unhomed(cold, ToolSettings{});
    CHECK_THROWS(JobError, unhomed.run_line("G1 X1 Y1"));
}

TEST_GROUP(CartesianTwin){};

TEST(CartesianTwin, applies_scale_and_squareness_errors) {
    CartesianTwin twin(CartesianErrors{0.001, -0.002, 0.1});
    twin.home();
    const Vec3 p = twin.actual_position_mm({100, 100, 1});
    // x = 100 * 1.001 + 100 * 0.998 * tan(0.1 deg), y = 100 * 0.998.
    DOUBLES_EQUAL(100.1 + 99.8 * 0.0017453310, p.x, 1e-7);
    DOUBLES_EQUAL(99.8, p.y, 1e-12);
    DOUBLES_EQUAL(1.0, p.z, 1e-12);
}

TEST(CartesianTwin, relative_moves_and_g92_offsets) {
    CartesianTwin twin(CartesianErrors{});
    const auto result = run_job(twin, "G28\nG92 X10 Y10\nG91\nG1 X5 E1\nG90\nG1 X10 Y20 E2\n");
    // G92 X10 Y10 at machine 0 makes relative X5 end at job X15, machine X5 (ten 0.5 mm
    // segments), and job (10, 20) machine (0, 10).
    CHECK_EQUAL(10u + 23u, result.strokes.size());
    DOUBLES_EQUAL(5.0, result.strokes[9].b_mm.x, 1e-9);
    DOUBLES_EQUAL(0.0, result.strokes[9].b_mm.y, 1e-9);
    DOUBLES_EQUAL(0.0, result.strokes.back().b_mm.x, 1e-9);
    DOUBLES_EQUAL(10.0, result.strokes.back().b_mm.y, 1e-9);
}

TEST(DeltaTwin, zeroing_at_the_centre_puts_the_nozzle_on_the_bed_there) {
    // Endstops off by tenths: homed, the firmware's Z0 is that far from the bed until zeroed.
    DeltaParams truth = kossel();
    truth.endstop_offset_mm = {-0.3, -0.1, -0.2};
    DeltaTwin twin(truth, kossel());
    twin.home();
    // The carriages stop 0.2 mm higher on average (the effector tilts nowhere: it stays level),
    // so the nozzle stops about 0.2 mm short of the bed.
    const double short_of_bed = twin.actual_position_mm({0, 0, 0}).z;
    DOUBLES_EQUAL(0.2, short_of_bed, 1e-3);
    twin.zero_height_at_centre();
    twin.home();
    DOUBLES_EQUAL(0.0, twin.actual_position_mm({0, 0, 0}).z, 1e-9);
    DOUBLES_EQUAL(kossel().height_mm + short_of_bed, twin.firmware().height_mm, 1e-9);
}

namespace {
DeltaParams off_in_every_parameter() {
    DeltaParams truth = kossel();
    truth.diagonal_rod_mm = 251.2;
    truth.diagonal_rod_trim_mm = {0.6, -0.4, -0.3};
    truth.radius_mm = 141;
    truth.tower_angle_trim_deg = {0.3, -0.2, 0.1};
    truth.endstop_offset_mm = {-0.3, -0.1, -0.2};
    return truth;
}
}  // namespace

TEST_GROUP(FirstLayer){};

TEST(FirstLayer, a_strand_is_pressed_to_the_gap_then_lies_as_a_free_bead) {
    // 0.45 x 0.2 mm of cross-section: 0.09 mm^2. Worked by hand:
    // at a 0.1 mm gap it is pressed to 0.1 mm and spreads to 0.09 / 0.1 = 0.9 mm;
    // at 0.2 mm it is as commanded, 0.45 mm;
    // a free bead is sqrt(4 * 0.09 / pi) = 0.338514 mm across, so from that gap on its top
    // stays there and its width is 0.09 / 0.338514 = 0.265868 mm;
    // at 0.05 mm it would spread to 1.8 mm: the 1.0 mm tip's flat stops it.
    const double area = 0.09, tip = 1.0;
    const auto pressed = first_layer_strand(area, 0.1, tip);
    DOUBLES_EQUAL(0.1, pressed.height_mm, 1e-12);
    DOUBLES_EQUAL(0.9, pressed.width_mm, 1e-12);
    CHECK_FALSE(pressed.free_bead);
    DOUBLES_EQUAL(0.45, first_layer_strand(area, 0.2, tip).width_mm, 1e-12);
    for (const double gap : {0.34, 0.5, 1.0}) {
        const auto bead = first_layer_strand(area, gap, tip);
        CHECK(bead.free_bead);
        DOUBLES_EQUAL(0.338514, bead.height_mm, 1e-6);
        DOUBLES_EQUAL(0.265868, bead.width_mm, 1e-6);
    }
    const auto scraped = first_layer_strand(area, 0.05, tip);
    DOUBLES_EQUAL(1.0, scraped.width_mm, 1e-12);
    DOUBLES_EQUAL(0.05, scraped.height_mm, 1e-12);
    DOUBLES_EQUAL(0.01, first_layer_strand(area, -0.1, tip).height_mm, 1e-12);
    CHECK_THROWS(std::invalid_argument, first_layer_strand(0, 0.2, tip));
}

TEST(FirstLayer, the_twin_lays_the_first_layer_by_its_gap_and_later_layers_as_commanded) {
    // The square job's strands are 0.601320 mm x 0.2 mm (stroke_width_follows_extruded_volume):
    // 0.120264 mm^2. Endstops that stop every carriage 0.05 mm higher leave the nozzle 0.05 mm
    // higher everywhere: a 0.25 mm gap, a strand pressed to 0.25 mm and 0.481056 mm wide.
    DeltaParams truth = kossel();
    truth.endstop_offset_mm = {-0.05, -0.05, -0.05};
    DeltaTwin twin(truth, kossel());
    ToolSettings tool;
    tool.real_first_layer = true;
    GcodeRunner runner(twin, tool);
    std::istringstream job(std::string(kSquareJob) + "G0 Z0.4\nG1 X20 Y-20 E10\n");
    runner.run(job);
    const auto& first = runner.result().strokes.front();
    DOUBLES_EQUAL(0.25, first.top_a_mm, 1e-3);
    DOUBLES_EQUAL(0.481056, first.width_mm, 1e-3);
    // The second layer (the last stroke) keeps its commanded width and its top at the nozzle,
    // whatever the gap: the job commanded it a layer up.
    const auto& second = runner.result().strokes.back();
    DOUBLES_EQUAL(0.601320, second.width_mm, 1e-5);
    DOUBLES_EQUAL(second.b_mm.z, second.top_b_mm, 1e-12);
}

TEST(FirstLayer, a_first_layer_far_off_the_bed_is_still_a_free_bead) {
    // Endstops that stop every carriage 0.3 mm higher: a 0.5 mm gap under a first layer
    // commanded at 0.2 mm. It lies as a free bead (top sqrt(4 * 0.120264 / pi) = 0.391312 mm),
    // not as a second layer would (0.601320 mm wide, its top at the nozzle).
    DeltaParams truth = kossel();
    truth.endstop_offset_mm = {-0.3, -0.3, -0.3};
    DeltaTwin twin(truth, kossel());
    ToolSettings tool;
    tool.real_first_layer = true;
    GcodeRunner runner(twin, tool);
    std::istringstream job(kSquareJob);
    runner.run(job);
    const auto& first = runner.result().strokes.front();
    DOUBLES_EQUAL(0.391312, first.top_a_mm, 1e-5);
    DOUBLES_EQUAL(0.120264 / 0.391312, first.width_mm, 1e-5);
}

TEST(FirstLayer, a_paper_test_zeroes_the_towers_and_centre_and_leaves_the_rest) {
    const DeltaParams truth = off_in_every_parameter();
    DeltaTwin twin(truth, kossel());
    twin.zero_height_at_centre();
    twin.level_by_paper(68);
    twin.home();
    for (const double deg : {210.0, 330.0, 90.0, 0.0}) {
        const double r = deg == 0.0 ? 0 : 68;
        DOUBLES_EQUAL(
            0.0,
            twin.actual_position_mm({r * std::cos(radians(deg)), r * std::sin(radians(deg)), 0}).z,
            1e-6);
    }
    // Marlin's gauge: the largest offset is zero, none positive.
    const auto& e = twin.firmware().endstop_offset_mm;
    DOUBLES_EQUAL(0.0, *std::max_element(e.begin(), e.end()), 1e-12);
    // Between the points the radius error is still there: opposite a tower, at the same
    // radius, the nozzle is off the bed.
    const double opposite =
        twin.actual_position_mm({68 * std::cos(radians(30)), 68 * std::sin(radians(30)), 0}).z;
    CHECK(std::abs(opposite) > 0.02);
}

TEST(FirstLayer, a_probe_routine_flattens_what_the_paper_test_leaves) {
    const DeltaParams truth = off_in_every_parameter();
    double worst_paper = 0, worst_probe = 0;
    for (const bool probe : {false, true}) {
        DeltaTwin twin(truth, kossel());
        twin.zero_height_at_centre();
        probe ? twin.level_by_probe(76) : twin.level_by_paper(68);
        twin.home();
        double lo = 1e9, hi = -1e9;
        for (int k = 0; k < 200; ++k) {
            const double r = 80 * std::sqrt((k + 0.5) / 200), a = k * 2.399963;
            const double z = twin.actual_position_mm({r * std::cos(a), r * std::sin(a), 0}).z;
            lo = std::min(lo, z), hi = std::max(hi, z);
        }
        (probe ? worst_probe : worst_paper) = hi - lo;
    }
    UT_PRINT(("bed height range after a paper test " + std::to_string(worst_paper) +
              " mm, after a probe routine " + std::to_string(worst_probe) + " mm")
                 .c_str());
    CHECK_TEXT(worst_paper > 0.1, std::to_string(worst_paper).c_str());
    CHECK_TEXT(worst_probe < 0.04, std::to_string(worst_probe).c_str());
}
