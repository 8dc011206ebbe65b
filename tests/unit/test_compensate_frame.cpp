// Jobs compensated where the machine really is: the work zero placed, the travel refused beyond,
// the correction held at the measured area's edge; canned cycles' holes; R arcs as controllers
// take them; words by flavour; LinuxCNC's language; the mark that stops a second pass. Every
// expected figure below is worked by hand from the correction and the job.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "core/jobs/compensate.hpp"
#include "core/gcode/gcode_line.hpp"
#include "core/jobs/ngc_program.hpp"
#include "core/modes/compensate_job.hpp"
#include "core/modes/planar.hpp"

using namespace calbox;
using geometry::Point2;

namespace {

constexpr double kPi = 3.14159265358979323846;

// 1 % long in x about the machine's origin, and y shifted by a thousandth of x: a correction
// that is not the same everywhere, so that a job placed at the wrong spot comes out wrong.
const jobs::Correction kStretched = [](Point2 p) { return Point2{1.01 * p.x, p.y + 0.001 * p.x}; };
// Measured over X 10..290, Y 10..290 on a 300 x 300 machine.
const jobs::Area kMeasured{10, 10, 290, 290};
const jobs::Area kTravel{0, 0, 300, 300};

std::vector<std::string> lines_of(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) out.push_back(l);
    return out;
}

// jobs::compensate_gcode for these tests' jobs: LinuxCNC stops on a job without its end (M2),
// so a LinuxCNC job without one gets it, taken off the output again, and the lines these tests
// read are the job's own.
std::string compensate_job(const std::string& job, const jobs::MachineCorrection& c,
                           const jobs::JobFrame& frame, const jobs::CompensateSettings& s,
                           jobs::CompensateReport& report) {
    const bool ended = job.find("M2") != std::string::npos || job.find("M30") != std::string::npos;
    if (frame.flavour != jobs::Flavour::linuxcnc || ended)
        return jobs::compensate_gcode(job, c, frame, s, report);
    std::string out = jobs::compensate_gcode(job + "M2\n", c, frame, s, report);
    CHECK_EQUAL(std::string("M2\n"), out.substr(out.size() - 3));
    out.resize(out.size() - 3);
    --report.lines;
    return out;
}

std::string compensated(const std::string& job, const jobs::JobFrame& frame,
                        jobs::CompensateReport& report, const jobs::Correction& c = kStretched) {
    jobs::CompensateSettings s;
    s.max_segment_mm = 1000;  // one piece a move: the end points are what these tests read
    return compensate_job(job, {c, kMeasured}, frame, s, report);
}
std::string compensated(const std::string& job, const jobs::JobFrame& frame) {
    jobs::CompensateReport report;
    return compensated(job, frame, report);
}

jobs::JobFrame router_at(Point2 work_zero) {
    return {jobs::Flavour::linuxcnc, {work_zero}, kTravel, {}};
}

std::string refusal_of(const std::string& job, const jobs::JobFrame& frame) {
    try {
        compensated(job, frame);
    } catch (const jobs::CompensateError& e) {
        return e.what();
    }
    return "not refused";
}

Point2 xy_of(const std::string& line) {
    const auto l = gcode::parse_line(line);
    return {*l.value('X'), *l.value('Y')};
}

}  // namespace

TEST_GROUP(CompensateFrame){};

TEST(CompensateFrame, the_job_is_corrected_at_its_place_on_the_machine) {
    // G54 at machine (100, 150): the job's X0 Y0 is the machine's (100, 150), corrected to
    // (101, 150.1): the job's (1, 0.1). At the machine's origin the same line would be (0, 0).
    const auto out = lines_of(compensated("G90\nG0 X0 Y0\nG0 X20 Y-40\n", router_at({100, 150})));
    const Point2 a = xy_of(out[1]), b = xy_of(out[2]);
    DOUBLES_EQUAL(1, a.x, 1e-9);
    DOUBLES_EQUAL(0.1, a.y, 1e-9);
    // (120, 110) -> (121.2, 110.12) -> the job's (21.2, -39.88).
    DOUBLES_EQUAL(21.2, b.x, 1e-9);
    DOUBLES_EQUAL(-39.88, b.y, 1e-9);
}

TEST(CompensateFrame, inside_at_the_edge_beyond_it_and_past_the_travel) {
    jobs::CompensateReport report;
    const auto out = lines_of(compensated(
        "G90\nG0 X100 Y100\nG0 X290 Y100\nG0 X295 Y100\nG0 X5 Y295\n", router_at({0, 0}), report));
    // Inside: the model's value.
    DOUBLES_EQUAL(101, xy_of(out[1]).x, 1e-9);
    // At the edge: still the model's, 2.9 mm more.
    DOUBLES_EQUAL(292.9, xy_of(out[2]).x, 1e-9);
    DOUBLES_EQUAL(100.29, xy_of(out[2]).y, 1e-9);
    // 5 mm beyond: the edge's correction (+2.9, +0.29) held, not the model's (+2.95, +0.295).
    DOUBLES_EQUAL(297.9, xy_of(out[3]).x, 1e-9);
    DOUBLES_EQUAL(100.29, xy_of(out[3]).y, 1e-9);
    // Beyond two edges: the corner (10, 290)'s correction (+0.1, +0.01).
    DOUBLES_EQUAL(5.1, xy_of(out[4]).x, 1e-9);
    DOUBLES_EQUAL(295.01, xy_of(out[4]).y, 1e-9);
    CHECK_EQUAL(2, report.held);
    DOUBLES_EQUAL(std::hypot(5.0, 5.0), report.held_farthest_mm, 1e-9);
    // Past the travel: refused, naming the line, the point and the travel.
    const std::string far =
        refusal_of("G90 F300\nG0 X100 Y100\nG1 X1000 Y-1000\n", router_at({0, 0}));
    CHECK_TEXT(far.find("line 3: the point X1000 Y-1000 is at machine X1000 Y-1000 mm, beyond "
                        "the machine's travel (X 0..300, Y 0..300 mm)") != std::string::npos,
               far.c_str());
    // The same job placed with its zero at (250, 250): X60 is machine 310, past the travel.
    const std::string placed = refusal_of("G90\nG0 X60 Y0\n", router_at({250, 250}));
    CHECK_TEXT(
        placed.find("line 2: the point X60 Y0 is at machine X310 Y250 mm") != std::string::npos,
        placed.c_str());
    // An arc that bulges past the travel, though both its ends are inside.
    const std::string bulge =
        refusal_of("G90 F300\nG0 X290 Y100\nG3 X290 Y120 I0 J10\n", router_at({5, 0}));
    CHECK_TEXT(bulge.find("beyond the machine's travel") != std::string::npos, bulge.c_str());
}

TEST(CompensateFrame, work_offsets_set_in_the_job_and_given_are_tracked) {
    // G10 L2 P1 sets G54's zero to machine (50, 60); G10 L20 P2 makes the current machine point
    // (70, 60) read X0 Y0 in G55.
    const auto out = lines_of(compensated(
        "G90\nG10 L2 P1 X50 Y60\nG0 X0 Y0\nG0 X20 Y0\nG10 L20 P2 X0 Y0\nG55\nG0 X10 Y0\n",
        router_at({0, 0})));
    // Machine (50, 60) -> (50.5, 60.05): the job's (0.5, 0.05).
    DOUBLES_EQUAL(0.5, xy_of(out[2]).x, 1e-9);
    DOUBLES_EQUAL(0.05, xy_of(out[2]).y, 1e-9);
    // In G55 X10 is machine 80 -> 80.8, 60.08: the job's 10.8, 0.08.
    DOUBLES_EQUAL(10.8, xy_of(out.back()).x, 1e-9);
    DOUBLES_EQUAL(0.08, xy_of(out.back()).y, 1e-9);
    // A move in a system whose zero nothing gives is refused, saying how to give it.
    const std::string unknown = refusal_of("G56\nG0 X1 Y1\n", router_at({0, 0}));
    CHECK_TEXT(unknown.find("line 2: a move in G56, whose zero the controller holds and the file "
                            "does not set: give it (calbox compensate --work-zero G56=X,Y") !=
                   std::string::npos,
               unknown.c_str());
}

TEST(CompensateFrame, printers_retract_with_g10_routers_set_offsets_with_it) {
    const jobs::JobFrame printer{jobs::Flavour::printer, {Point2{}}, kTravel, {}};
    // FullControl's firmware retraction: passed as written.
    const auto out = lines_of(compensated("G90\nG1 X100 Y100\nG10 ; retract\nG11\n", printer));
    CHECK_EQUAL(std::string("G10 ; retract"), out[2]);
    CHECK_EQUAL(std::string("G11"), out[3]);
    // RepRapFirmware's tool offset is refused; on a router a bare G10 is.
    CHECK(refusal_of("G10 P0 X5 Y0\n", printer)
              .find("line 1: G10 P with X or Y sets a tool's "
                    "offset") != std::string::npos);
    CHECK(refusal_of("G10 ; retract\n", router_at({0, 0})).find("line 1: G10 without L") !=
          std::string::npos);
}

TEST(CompensateFrame, an_r_arc_short_within_the_written_precision_is_a_half_circle) {
    // Fusion 360 writes 3 decimals: from (0.257, 16.041) to (0.257, 19.058) the half chord is
    // 1.5085 and R 1.508 is 0.0005 short: the half circle its rounding hid.
    const jobs::Correction none = [](Point2 p) { return p; };
    jobs::CompensateReport report;
    jobs::CompensateSettings s;
    const jobs::JobFrame frame{jobs::Flavour::grbl, {Point2{}}, {}, {}};
    const auto out =
        lines_of(compensate_job("G90 F300\nG0 X0.257 Y16.041 Z3\nG3 X0.257 Y19.058 Z2.38 R1.508\n",
                                {none, {}}, frame, s, report));
    double farthest = 0;
    for (std::size_t i = 2; i < out.size(); ++i) {
        const Point2 p = xy_of(out[i]);
        DOUBLES_EQUAL(1.5085, std::hypot(p.x - 0.257, p.y - 17.5495), 0.0002);
        farthest = std::max(farthest, p.x - 0.257);
    }
    // Anticlockwise from the lower end to the upper: the half circle on the +x side.
    DOUBLES_EQUAL(1.5085, farthest, 0.002);
    // 0.002 short in a 3-decimal file: refused with its figures.
    const auto refused = [&] {
        try {
            compensate_job("G90 F300\nG0 X0 Y0\nG2 X3 Y0 R1.498\n", {none, {}}, frame, s, report);
        } catch (const jobs::CompensateError& e) {
            return std::string(e.what());
        }
        return std::string("not refused");
    }();
    CHECK_TEXT(
        refused.find("line 3: an R arc no controller could cut: radius 1.498 mm, chord 3 mm, "
                     "so R is 0.002 mm short of half the chord, past the file's written "
                     "precision of 0.001 mm") != std::string::npos,
        refused.c_str());
}

TEST(CompensateFrame, drilling_cycles_keep_each_hole_through_the_correction) {
    jobs::CompensateReport report;
    // LinuxCNC keeps the cycle: each hole's XY corrected, its other words as written.
    const auto kept =
        lines_of(compensated("G90 G0 X0 Y0 Z10\nG99 G81 X100 Y50 Z-2 R1 F300\nX200 Y50\nG80\n",
                             router_at({0, 0}), report));
    CHECK_EQUAL(std::string("G99 G81 X101 Y50.1 R1 Z-2 F300"), kept[1]);
    CHECK_EQUAL(std::string("G81 X202 Y50.2"), kept[2]);
    CHECK_EQUAL(std::string("G80"), kept[3]);
    CHECK_EQUAL(2, report.holes);
    // Incremental repeats: L3 holes 10 mm apart from x = 100, each its own line, written as
    // differences of the corrected holes (111.1, 121.2, 131.3). LinuxCNC takes an incremental R
    // from the height the series of cycles started at (Z 10), under G98 and G99 alike (its rs274
    // reads a later block's R0 as Z 10, not as the R plane the last hole left): R -9 on the first
    // line stays in force for the others, which write none.
    for (const bool to_r : {false, true}) {
        const auto repeats =
            lines_of(compensated(std::string("G90 G0 X100 Y100 Z10 F300\nG91 ") +
                                     (to_r ? "G99" : "G98") + " G81 X10 Y0 Z-3 R-9 L3\n",
                                 router_at({0, 0})));
        CHECK_EQUAL(4u, repeats.size());
        double x = 100 * 1.01;
        for (std::size_t k = 1; k <= 3; ++k) {
            const auto l = gcode::parse_line(repeats[k]);
            x += *l.value('X');
            DOUBLES_EQUAL(1.01 * (100 + 10 * k), x, 1e-4);
            if (k == 1)
                DOUBLES_EQUAL(-9, *l.value('R'), 1e-9);
            else
                CHECK_FALSE(l.has('R'));
            DOUBLES_EQUAL(-3, *l.value('Z'), 1e-9);
        }
    }
    // grbl has no cycles (nor G98 / G99): G83 written out as pecks of 1 mm to Z-2.5, back to R
    // between them, down to 0.254 mm above the last depth, then back to where it started (G98:
    // Z 5).
    const jobs::JobFrame grbl{jobs::Flavour::grbl, {Point2{}}, kTravel, {}};
    const auto pecks =
        lines_of(compensated("G90 G0 X0 Y0 Z5\nG98 G83 X100 Y100 Z-2.5 R0.5 Q1 F200\n", grbl));
    const std::vector<std::string> expected{
        // (0, 0) lies beyond the measured area: its corner's correction (+0.1, +0.01), held.
        "G90 G0 X0.1 Y0.01 Z5",
        "G0 X101 Y100.1 F200",
        "G0 Z0.5",
        "G1 Z-0.5",
        "G0 Z0.5",
        "G0 Z-0.246",
        "G1 Z-1.5",
        "G0 Z0.5",
        "G0 Z-1.246",
        "G1 Z-2.5",
        "G0 Z5"};
    CHECK_EQUAL(expected.size(), pecks.size());
    for (std::size_t i = 0; i < expected.size() && i < pecks.size(); ++i)
        CHECK_EQUAL(expected[i], pecks[i]);
    // A tapping cycle cannot be written out as moves: refused, saying so.
    CHECK(refusal_of("G90 G0 X0 Y0 Z5 F300\nG84 X10 Y10 Z-2 R1\n", grbl)
              .find("line 2: canned cycle G84") != std::string::npos);
}

TEST(CompensateFrame, linuxcnc_programs_run_into_the_moves_linuxcnc_makes) {
    // A subroutine called in a loop with numbered, named and global parameters and expressions:
    // holes at x = 10, 20, 30 (y = 2 x - 5 by the expression), then a polar move.
    const std::string program =
        "F300 #<_pitch> = 10\n"
        "o100 sub\n"
        "  G1 X#1 Y[#1 * 2 - 5]\n"
        "o100 endsub\n"
        "#<n> = 1\n"
        "G90 G0 X0 Y0\n"
        "o101 while [#<n> LE 3]\n"
        "  o100 call [#<n> * #<_pitch>]\n"
        "  #<n> = [#<n> + 1]\n"
        "o101 endwhile\n"
        "o102 if [EXISTS[#<n>] AND [#<n> EQ 4]]\n"
        "  G1 @50 ^30\n"
        "o102 else\n"
        "  G1 X0 Y0\n"
        "o102 endif\n"
        "M2\n"
        "G1 X299 Y299 (after the end: never run)\n";
    jobs::CompensateReport report;
    const auto out = lines_of(compensated(program, router_at({100, 100}), report));
    CHECK(report.ran_program);
    std::vector<Point2> moves;
    for (const auto& l : out) {
        const auto parsed = gcode::parse_line(l);
        if (parsed.is('G', 1)) moves.push_back(xy_of(l));
    }
    CHECK_EQUAL(4u, moves.size());
    for (std::size_t k = 0; k < 3; ++k) {
        const double jx = 10.0 * (k + 1), jy = 2 * jx - 5;
        const Point2 machine{jx + 100, jy + 100};
        DOUBLES_EQUAL(1.01 * machine.x - 100, moves[k].x, 1e-4);
        DOUBLES_EQUAL(machine.y + 0.001 * machine.x - 100, moves[k].y, 1e-4);
    }
    // @50 ^30 from the work zero: (43.3013, 25), corrected at machine (143.3013, 125).
    const Point2 polar{50 * std::cos(kPi / 6), 50 * std::sin(kPi / 6)};
    DOUBLES_EQUAL(1.01 * (polar.x + 100) - 100, moves[3].x, 1e-4);
    DOUBLES_EQUAL(polar.y + 0.001 * (polar.x + 100), moves[3].y, 1e-4);
    CHECK_EQUAL(std::string("M2"), out.back());
    // Runaway loops and reads of the controller's own parameters are refused.
    gcode::ProgramLimits small;
    small.max_loop_turns = 1000;
    CHECK_THROWS(gcode::ProgramError,
                 gcode::run_ngc_program("o1 while [1]\nG0 X0 Y0\no1 endwhile\n", small));
    const std::string system = refusal_of("G0 X#5221 Y0\n", router_at({0, 0}));
    CHECK_TEXT(system.find("line 1: #5221 is the controller's own") != std::string::npos,
               system.c_str());
    const std::string unset = refusal_of("G0 X#<nowhere> Y0\n", router_at({0, 0}));
    CHECK_TEXT(unset.find("line 1: named parameter #<nowhere> is read before it is set") !=
                   std::string::npos,
               unset.c_str());
}

TEST(CompensateFrame, expressions_follow_linuxcncs_precedence_and_functions) {
    const auto value_of = [](const std::string& expression) {
        const auto lines = gcode::run_ngc_program("G0 X" + expression + " Y0\n");
        return *gcode::parse_line(lines.at(0).text).value('X');
    };
    DOUBLES_EQUAL(7, value_of("[1 + 2 * 3]"), 1e-12);
    DOUBLES_EQUAL(-7, value_of("[1 - 2 ** 3]"), 1e-12);
    DOUBLES_EQUAL(2, value_of("[-7 MOD 3]"), 1e-12);  // LinuxCNC's MOD is never negative
    DOUBLES_EQUAL(1, value_of("[2 GT 1 AND 3 LE 3]"), 1e-12);
    DOUBLES_EQUAL(0.5, value_of("SIN[30]"), 1e-9);
    DOUBLES_EQUAL(135, value_of("ATAN[1]/[-1]"), 1e-9);
    DOUBLES_EQUAL(3, value_of("FUP[2.1]"), 1e-12);
    DOUBLES_EQUAL(-3, value_of("FIX[-2.1]"), 1e-12);
    // Assignments take effect after the line is read, as LinuxCNC reads it; a line of
    // assignments alone leaves nothing to run.
    const auto lines = gcode::run_ngc_program("#1 = 5\n#1 = 7 G0 X#1 Y0\nG0 X#1 Y0\n");
    CHECK_EQUAL(2u, lines.size());
    CHECK_EQUAL(std::string("G0 X5 Y0"), lines.at(0).text);
    CHECK_EQUAL(2, lines.at(0).source_line);
    CHECK_EQUAL(std::string("G0 X7 Y0"), lines.at(1).text);
}

TEST(CompensateFrame, inverse_time_feed_is_shared_among_a_moves_pieces) {
    // G93: F2 finishes the 4 mm move in half a minute; split in four pieces, each takes an eighth
    // (F8), so the whole still takes half a minute.
    jobs::CompensateReport report;
    jobs::CompensateSettings s;
    const auto out =
        lines_of(compensate_job("G90 G0 X100 Y100\nG93 G1 X104 Y100 F2\n", {kStretched, kMeasured},
                                router_at({0, 0}), s, report));
    CHECK_EQUAL(5u, out.size());
    for (std::size_t i = 1; i < out.size(); ++i)
        DOUBLES_EQUAL(8, *gcode::parse_line(out[i]).value('F'), 1e-12);
}

TEST(CompensateFrame, a_rotary_axis_is_shared_along_the_pieces_and_arcs_take_their_turns) {
    // A 4 mm move turning A from 0 to 40 degrees: each 1 mm piece turns it 10 more.
    jobs::CompensateReport report;
    jobs::CompensateSettings s;
    const auto out =
        lines_of(compensate_job("G90 G0 X100 Y100 A0\nG1 X104 Y100 A40 F300\n",
                                {kStretched, kMeasured}, router_at({0, 0}), s, report));
    CHECK_EQUAL(5u, out.size());
    for (std::size_t k = 1; k <= 4; ++k)
        DOUBLES_EQUAL(10.0 * k, *gcode::parse_line(out[k]).value('A'), 1e-9);
    // Driving A from where the file never said is refused: the share is unknown.
    std::string unknown_a;
    try {
        compensate_job("G90 G0 X100 Y100 F300\nG1 X104 Y100 A40\n", {kStretched, kMeasured},
                       router_at({0, 0}), s, report);
    } catch (const jobs::CompensateError& e) {
        unknown_a = e.what();
    }
    CHECK_TEXT(unknown_a.find("line 2: a move that drives A from where the file has not said") !=
                   std::string::npos,
               unknown_a.c_str());
    // LinuxCNC's P: three whole turns round a 1 mm circle, about three times the chords of one.
    const jobs::Correction none = [](Point2 p) { return p; };
    jobs::CompensateSettings fine;
    fine.max_segment_mm = 0.1;
    const auto one = compensate_job("G90 G0 X101 Y100 F300\nG2 X101 Y100 I-1 J0\n", {none, {}},
                                    router_at({0, 0}), fine, report);
    const auto three = compensate_job("G90 G0 X101 Y100 F300\nG2 X101 Y100 I-1 J0 P3\n", {none, {}},
                                      router_at({0, 0}), fine, report);
    const double ratio = static_cast<double>(lines_of(three).size() - 1) /
                         static_cast<double>(lines_of(one).size() - 1);
    DOUBLES_EQUAL(3, ratio, 0.05);
    // A subprogram call is refused: its lines would run out of the file's order.
    CHECK(refusal_of("G0 X1 Y1\nM98 P1000\n", router_at({0, 0})).find("line 2: a subprogram") !=
          std::string::npos);
}

TEST(CompensateFrame, lathe_jobs_and_cutter_compensation_are_refused_as_such) {
    CHECK(refusal_of("G18 G7\nG0 X1 Z0\n", router_at({0, 0})).find("line 1: a lathe job (G7)") !=
          std::string::npos);
    CHECK(refusal_of("G0 X1 Y1\nG76 P0.05 Z-1 I-.075 J0.008 K0.045\n", router_at({0, 0}))
              .find("line 2: a lathe job (G76)") != std::string::npos);
}

namespace {

// A planar result with no error (the model zero) measured over X 12.5..287.5 Y 12.5..287.5 with
// its work zero at machine (5, 5) on a grbl router of 300 x 300 mm travel.
std::string planar_result_text(const std::string& firmware, const std::string& kind) {
    modes::PlanarSolution s;
    s.machine_fingerprint = "fnv1a64:0000000000000000";
    s.min_x_mm = s.min_y_mm = 12.5;
    s.max_x_mm = s.max_y_mm = 287.5;
    modes::PlanarFrame f;
    f.work_zero_mm = {5, 5};
    f.work_zero_from = "the machine file";
    f.travel_max_x_mm = f.travel_max_y_mm = 300;
    f.firmware = firmware;
    f.kind = kind;
    s.frame = f;
    return modes::planar_result_to_json(s, {});
}

modes::JobRequest request_for(const std::string& job) {
    modes::JobRequest r;
    r.result_text = planar_result_text("grbl", "router");
    r.result_name = "result.json";
    r.job_text = job;
    r.job_name = "job.nc";
    r.date = "2026-11-26T12:00:00Z";
    return r;
}

std::string job_refusal(const modes::JobRequest& r) {
    try {
        modes::compensate_job(r);
    } catch (const modes::JobError& e) {
        return e.what();
    }
    return "not refused";
}

}  // namespace

TEST(CompensateFrame, a_routers_job_needs_its_work_zero_and_is_compensated_once) {
    auto r = request_for("G90 F300\nG0 X0 Y0\nG1 X10 Y-5\n");
    const std::string no_zero = job_refusal(r);
    CHECK_TEXT(no_zero.find("job.nc: a router's job is written around its work zero, which "
                            "calbox cannot see: give --work-zero X,Y") != std::string::npos,
               no_zero.c_str());
    CHECK_TEXT(no_zero.find("zero at machine X5.000 Y5.000") != std::string::npos, no_zero.c_str());
    r.work_zero = "100,150";
    const auto done = modes::compensate_job(r);
    CHECK_TEXT(
        done.frame_line.find("G54 zero at machine X100.000 Y150.000 mm") != std::string::npos,
        done.frame_line.c_str());
    const auto out = lines_of(done.text);
    CHECK_TEXT(out[0].rfind("; calbox: compensated through result fnv1a64:", 0) == 0,
               out[0].c_str());
    CHECK(out[0].find("on 2026-11-26T12:00:00Z") != std::string::npos);
    // Measured X is machine - 5: the model is zero, so the job comes out as it went in.
    CHECK_EQUAL(std::string("G1 X10 Y-5"), out.back());
    // Again: refused, unless the owner says why.
    auto again = request_for(done.text);
    again.work_zero = "measured";
    const std::string twice = job_refusal(again);
    CHECK_TEXT(twice.find("job.nc: already compensated (its line 'calbox: compensated through "
                          "result fnv1a64:") != std::string::npos,
               twice.c_str());
    again.again_because = "a second machine of the same build";
    CHECK(modes::compensate_job(again).text.find("(again: a second machine") != std::string::npos);
    // A printer's job is in machine coordinates; --work-zero is refused there.
    auto printer = request_for("G90\nG1 X10 Y10\n");
    printer.result_text = planar_result_text("marlin", "cartesian");
    CHECK(modes::compensate_job(printer).frame_line.find("machine coordinates") !=
          std::string::npos);
    printer.work_zero = "1,1";
    CHECK(job_refusal(printer).find("a printer's job is in machine coordinates") !=
          std::string::npos);
    // A bad --work-zero names itself.
    r.work_zero = "G60=1,2";
    CHECK(job_refusal(r).find("--work-zero 'G60=1,2': 'G60' is no work system") !=
          std::string::npos);
}

TEST(CompensateFrame, a_scanners_job_stays_in_its_field) {
    // An identity table over X, Y -1..1 of a 10 mm field: a point at X 4 takes the table's edge
    // correction (none), one at X 6 is past the field and refused.
    auto r = request_for("x_mm,y_mm,power\n0,0,0\n4,0,0.5\n");
    r.result_text =
        R"({"schema": "calbox.galvo-result/1", "machine_fingerprint": "x", "pass": 1,
            "field_size_mm": 10,
            "before": {"mean_mm": 0, "rms_mm": 0, "max_mm": 0, "points": 0},
            "measurement_sigma_mm": 0, "predicted_rms_mm": 0, "table_interpolation_max_mm": 0,
            "table_interpolation_rms_mm": 0, "intended_mm": [], "landed_mm": [],
            "filled_nodes": [],
            "table": {"nodes": 2, "min_x_mm": -1, "min_y_mm": -1, "max_x_mm": 1, "max_y_mm": 1,
                      "command_mm": [[-1, -1], [1, -1], [-1, 1], [1, 1]]}})";
    const auto done = modes::compensate_job(r);
    CHECK(done.text.find("4.0000,0.0000,0.5") != std::string::npos);
    r.job_text = "x_mm,y_mm,power\n0,0,0\n6,0,0.5\n";
    CHECK(job_refusal(r).find("job.nc: line 3: the point 6,0 is beyond the field the machine "
                              "reaches") != std::string::npos);
}

// Issue 56's cases, each worked by hand through kStretched (x 1 % long, y + 0.001 x), one piece a
// move. LinuxCNC's interpreter reads the same (tests/cli/rs274_judge.py).
TEST(CompensateFrame, words_riding_on_modal_moves_are_corrected_with_them) {
    // grbl: M03 S1000 and M5 on modal G1 lines. (0, 0) is beyond the measured area: its corner's
    // correction (+0.1, +0.01), held.
    const jobs::JobFrame grbl{jobs::Flavour::grbl, {Point2{}}, kTravel, {}};
    jobs::CompensateReport report;
    const auto out = lines_of(compensated(
        "G21 G90\nG0 X0 Y0\nG1 X120 Y100 F500\nX130 Y100 M03 S1000\nX150 Y100 M5\n", grbl, report));
    CHECK_EQUAL(std::string("G0 X0.1 Y0.01"), out[1]);
    CHECK_EQUAL(std::string("G1 X121.2 Y100.12 F500"), out[2]);
    CHECK_EQUAL(std::string("G1 X131.3 Y100.13 S1000 M3"), out[3]);
    CHECK_EQUAL(std::string("G1 X151.5 Y100.15 M5"), out[4]);
    CHECK_EQUAL(4, report.moves);
    // A stop rides after the move: M2 on the last piece.
    jobs::CompensateSettings s;
    const auto split =
        lines_of(compensate_job("G90 G0 X100 Y100\nG1 X102 Y100 F100 M8 M2\n",
                                {kStretched, kMeasured}, router_at({0, 0}), s, report));
    CHECK_EQUAL(std::string("G1 X102.01 Y100.101 F100 M8"), split[1]);
    CHECK_EQUAL(std::string("G1 X103.02 Y100.102 M2"), split[2]);
}

TEST(CompensateFrame,
     offsets_set_mid_job_are_rewritten_so_the_controller_zero_is_the_intended_one) {
    // The tool stands at the corrected (101, 100.1) when G92 says "here is 0, 0": the controller
    // is told it reads (1, 0.1) there, so its zero is at machine (100, 100) as the job meant, and
    // X20 Y10 (machine 120, 110, sent to 121.2, 110.12) is written X21.2 Y10.12.
    for (const std::string offset : {"G92 X0 Y0", "G10 L20 P1 X0 Y0"}) {
        const auto out = lines_of(
            compensated("G90 G0 X100 Y100\n" + offset + "\nG0 X20 Y10\n", router_at({0, 0})));
        CHECK_EQUAL(std::string("G90 G0 X101 Y100.1"), out[0]);
        CHECK_EQUAL(offset.substr(0, offset.size() - 5) + "X1 Y0.1", out[1]);
        CHECK_EQUAL(std::string("G0 X21.2 Y10.12"), out[2]);
    }
    // G10 L2 sets the zero in machine coordinates: as written.
    const auto l2 = lines_of(
        compensated("G90 G0 X100 Y100\nG10 L2 P1 X50 Y50\nG0 X20 Y10\n", router_at({0, 0})));
    CHECK_EQUAL(std::string("G10 L2 P1 X50 Y50"), l2[1]);
    // X20 Y10 in the new frame: machine (70, 60), sent to (70.7, 60.07), X20.7 Y10.07 there.
    CHECK_EQUAL(std::string("G0 X20.7 Y10.07"), l2[2]);
    // T2Laser's opening G92 before any move says the head is where it stands: at machine
    // (100, 100) the owner says, it reads (42.2, 49.95), so X52.2 Y59.95 is machine (110, 110).
    jobs::JobFrame laser{jobs::Flavour::grbl, {Point2{}}, kTravel, Point2{100, 100}};
    const auto t2 = lines_of(compensated("G21\nG90\nG92X42.2Y49.95\nG0 X52.2 Y59.95\n", laser));
    CHECK_EQUAL(std::string("G92 X42.2 Y49.95"), t2[2]);
    CHECK_EQUAL(std::string("G0 X53.3 Y60.06"), t2[3]);
    // Without where it starts, refused naming the option.
    CHECK(refusal_of("G21\nG92X42.2Y49.95\nG0 X52.2 Y59.95\n",
                     {jobs::Flavour::grbl, {Point2{}}, kTravel, {}})
              .find("line 2: G92 with X or Y before the position is known") != std::string::npos);
    // G52 on LinuxCNC sets the offset itself, not from where the tool is: as written, and the
    // next point placed by it (X10 Y5 at machine 60, 25: sent to 60.6, 25.06).
    const auto g52 =
        lines_of(compensated("G90 G0 X100 Y100\nG52 X50 Y20\nG0 X10 Y5\n", router_at({0, 0})));
    CHECK_EQUAL(std::string("G52 X50 Y20"), g52[1]);
    CHECK_EQUAL(std::string("G0 X10.6 Y5.06"), g52[2]);
}

TEST(CompensateFrame, words_are_read_as_the_controllers_read_them) {
    // Blanks inside a number count for nothing (RS274NGC): X 1 0 . 5 is X10.5, sent to 10.605.
    const auto spaced =
        lines_of(compensated("G90 G0 X20 Y20\nG1 X 1 0 . 5 Y2 0 F100\n", router_at({0, 0})));
    CHECK_EQUAL(std::string("G1 X10.605 Y20.0105 F100"), spaced[1]);
    // Lower case letters, and a leading '+' and '.'.
    const auto lower = lines_of(compensated("g90 g0 x20 y20\ng1 x30 f100\n", router_at({0, 0})));
    CHECK_EQUAL(std::string("G90 G0 X20.2 Y20.02"), lower[0]);
    CHECK_EQUAL(std::string("G1 X30.3 Y20.03 F100"), lower[1]);
    // (20, 0.5) is beyond the measured area: (20, 10)'s correction (+0.2, +0.02), held.
    const auto plus = lines_of(
        compensated("G90 G0 X20 Y20 F300\nG1 X+50. Y+20.\nG1 X+20. Y+.5\n", router_at({0, 0})));
    CHECK_EQUAL(std::string("G1 X50.5 Y20.05"), plus[1]);
    CHECK_EQUAL(std::string("G1 X20.2 Y0.52"), plus[2]);
    // What LinuxCNC and grbl stop on is refused, naming the line, the column and the word.
    const auto refused = [&](const std::string& job, const std::string& see) {
        const std::string why = refusal_of(job, router_at({0, 0}));
        CHECK_TEXT(why.find(see) != std::string::npos, why.c_str());
    };
    refused("G0 X0 Y0\nG1 X30 Y3O F100\n", "line 2: column 10: 'O': the controller has no O word");
    refused("G0 X1e5 Y10\n", "line 1: column 6: 'e': the controller has no E word");
    refused("G0 X0 Y0\nG1 X10 Y2 K3 F100\n", "line 2: K word with no G2 or G3 to use it");
    refused("G0 X0 Y0\nG1 X1 X2 F10\n", "line 2: two X words on one line");
    refused("G0 G1 X1 Y1 F10\n", "line 1: two G codes of one modal group on one line (G0 and G1)");
    refused("G0 X1 Y1\nG80\nX2 Y2\n", "line 3: axis words with no motion in force");
    refused("G0 X1.2.3 Y1\n", "line 1: column 4: 'X1.2.': '.' is no part of a number");
    // A comment ends a number (LinuxCNC: "Bad character '9' used"), and stands in none.
    refused("G0 X1(one)9 Y0\n", "line 1: column 11: '9' where a word's letter should be");
    refused("G0 X(here)1 Y0\n", "line 1: column 5: a comment between 'X' and its number");
    refused("G0 X0 Y0\nG1 X10 F100 M3 S-1000\n", "line 2: 'S-1000': a negative spindle speed");
    refused("G0 X0 Y0\nG1 X10 F-100\n", "line 2: 'F-100': a negative feed rate");
    // A drilling cycle's retract plane below its bottom, also when Z stays in force.
    refused("G0 X0 Y0 Z5\nG99 G81 X10 Y10 Z-1 R1 F200\nX20 Z2\n",
            "line 3: canned cycle G81 with its retract plane R1 below the hole's bottom Z2");
    refused("G0 X0 Y0 Z5\nG91 G99 G81 X10 Y0 Z1 R-1 F100\n",
            "line 2: canned cycle G81 with its retract plane R-1 below the hole's bottom Z1 (G91");
    // R and Z kept only while the same cycle goes on; a dwelling cycle's P; G86's spindle; an M
    // code with a fraction.
    refused("G0 X0 Y0 Z10\nG99 G81 X0 Y0 Z-3 R9 F100\nG80\nG81 X5 Y0\n",
            "line 4: canned cycle G81 without its R or Z");
    refused("G0 X0 Y0 Z10\nG99 G82 X0 Y0 Z-3 R9 F100 P1\nG81 X5 Y0\n",
            "line 3: canned cycle G81 without its R or Z");
    refused("G0 X0 Y0 Z10\nM3 S500\nG99 G88 X0 Y0 Z-3 R9 F100\n",
            "line 3: canned cycle G88 without its dwell (P)");
    refused("G0 X0 Y0 Z10\nM3 S500\nT1 M6\nG99 G86 X0 Y0 Z-3 R9 F100 P1\n",
            "line 4: canned cycle G86 with the spindle not turning");
    refused("G0 X0 Y0\nG1 X 1 M . 5 Y2 F100\n", "line 2: M0.5: an M code is a whole number");
    // An XZ arc from a height the file has not given (rs274 would take Z0).
    refused("G0 X10 Y10\nG18 G2 X20 Z0 I5 K0 F100\n",
            "line 2: an arc in the XZ plane from a height the file has not given");
    // This file's helper ends LinuxCNC's jobs with M2; without it, LinuxCNC stops at the end.
    std::string unended;
    try {
        jobs::CompensateReport report;
        jobs::compensate_gcode("G0 X1 Y1\n", {kStretched, kMeasured}, router_at({0, 0}), {},
                               report);
    } catch (const jobs::CompensateError& e) {
        unended = e.what();
    }
    CHECK_TEXT(
        unended.find("line 1: the job ends without M2, M30 or a closing '%'") != std::string::npos,
        unended.c_str());
}

TEST(CompensateFrame, comments_are_kept_once_and_the_words_after_them_read) {
    // tort.ngc's line: the words after the inline comment are the arc's; the copy carries the
    // comment once and no word twice.
    const auto out = lines_of(compensated(
        "G90 G0 X100 Y100 Z13\nG17 G2 (270 360) I0 J7 X107 Y107 Z13 F100\n", router_at({0, 0})));
    const auto last = out[out.size() - 1];
    CHECK_EQUAL(std::string("G1 X108.07 Y107.107 Z13 (270 360)"), last);
    for (const auto& l : out) CHECK_EQUAL(std::string::npos, l.find("I0"));
}
