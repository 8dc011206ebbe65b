// Compensated jobs: every XY through the correction, moves split, arcs traced, the rest kept.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/jobs/compensate.hpp"
#include "core/gcode/gcode_line.hpp"

using namespace calbox;
using geometry::Point2;

namespace {

const jobs::Correction kIdentity = [](Point2 p) { return p; };
// A printer's job in machine coordinates, no travel limit, corrected everywhere.
const jobs::JobFrame kMachineFrame{jobs::Flavour::printer, {Point2{}}, {}, {}};

std::vector<std::string> lines_of(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) out.push_back(l);
    return out;
}

std::string compensated(const std::string& job, const jobs::Correction& c = kIdentity,
                        double segment = 1.0) {
    jobs::CompensateReport report;
    jobs::CompensateSettings s;
    s.max_segment_mm = segment;
    return jobs::compensate_gcode(job, {c, {}}, kMachineFrame, s, report);
}

}  // namespace

TEST_GROUP(Compensate){};

TEST(Compensate, moves_are_split_and_every_other_word_and_comment_is_kept) {
    const auto out = lines_of(
        compensated("; a job\nG21\nG90\nM3 S255\nG0 X0 Y0 F6000\nG1 X10 Y0 F1200 S200 ; burn\nM5\n",
                    [](Point2 p) {
                        return Point2{p.x + 1, p.y - 0.5};
                    }));
    // Header lines as written; the travel corrected; the 10 mm move in ten 1 mm pieces.
    CHECK_EQUAL(std::string("; a job"), out[0]);
    CHECK_EQUAL(std::string("M3 S255"), out[3]);
    CHECK_EQUAL(std::string("G0 X1 Y-0.5 F6000"), out[4]);
    CHECK_EQUAL(std::string("G1 X2 Y-0.5 F1200 S200"), out[5]);
    CHECK_EQUAL(std::string("G1 X3 Y-0.5"), out[6]);
    CHECK_EQUAL(std::string("G1 X11 Y-0.5 ; burn"), out[14]);
    CHECK_EQUAL(std::string("M5"), out[15]);
    CHECK_EQUAL(16u, out.size());
}

TEST(Compensate, extrusion_and_height_are_shared_along_the_pieces) {
    const auto out = lines_of(compensated("G90\nM82\nG1 X0 Y0 Z0.2 E0\nG1 X2 Y0 Z0.4 E1\n"));
    CHECK_EQUAL(std::string("G1 X1 Y0 Z0.3 E0.5"), out[3]);
    CHECK_EQUAL(std::string("G1 X2 Y0 Z0.4 E1"), out[4]);
    const auto relative = lines_of(compensated("M83\nG1 X0 Y0\nG1 X2 Y0 E1\n"));
    CHECK_EQUAL(std::string("G1 X1 Y0 E0.5"), relative[2]);
    CHECK_EQUAL(std::string("G1 X2 Y0 E0.5"), relative[3]);
}

TEST(Compensate, arcs_become_chords_on_the_circle) {
    // Half circles about (5, 0), all over the top: clockwise from (0, 0) by centre offset and
    // by radius, and anticlockwise from (10, 0).
    const std::vector<std::pair<std::string, std::string>> arcs{{"G1 X0 Y0\n", "G2 X10 Y0 I5 J0"},
                                                                {"G1 X0 Y0\n", "G2 X10 Y0 R5"},
                                                                {"G1 X10 Y0\n", "G3 X0 Y0 I-5 J0"}};
    for (const auto& [start, arc] : arcs) {
        const auto out = lines_of(compensated(start + arc + "\n", kIdentity, 0.5));
        double worst = 0;
        for (std::size_t i = 1; i < out.size(); ++i) {
            const auto l = gcode::parse_line(out[i]);
            CHECK(l.is('G', 1));
            const double r = std::hypot(*l.value('X') - 5, *l.value('Y'));
            worst = std::max(worst, std::abs(r - 5));
        }
        CHECK(worst < 1e-4);  // every chord end on the circle
        // README: each chord strays at most 0.002 mm from the arc (its middle is the farthest).
        double sag = 0;
        for (std::size_t i = 2; i < out.size(); ++i) {
            const auto a = gcode::parse_line(out[i - 1]), b = gcode::parse_line(out[i]);
            const double mx = (*a.value('X') + *b.value('X')) / 2;
            const double my = (*a.value('Y') + *b.value('Y')) / 2;
            sag = std::max(sag, 5 - std::hypot(mx - 5, my));
        }
        CHECK(sag <= 0.002 + 1e-4);  // and the output's 0.0001 mm digits
        CHECK(sag > 0.0002);  // chords, not points: the pieces are as long as the tolerance allows
        CHECK(out.size() > 30);  // half a circle of 15.7 mm at most 0.5 mm a chord
        // Clockwise from (0, 0) to (10, 0) about (5, 0) passes over the top (y > 0).
        const double middle_y = *gcode::parse_line(out[out.size() / 2]).value('Y');
        CHECK(middle_y > 4);
    }
}

TEST(Compensate, what_cannot_be_carried_through_is_refused_naming_the_line) {
    const auto refused = [](const std::string& job, const std::string& words) {
        try {
            compensated(job);
        } catch (const jobs::CompensateError& e) {
            const std::string what = e.what();
            CHECK_TEXT(what.find(words) != std::string::npos, what.c_str());
            return;
        }
        FAIL(("not refused: " + job).c_str());
    };
    refused("G1 X1\n", "line 1: a move that gives one axis");
    refused("G1 X0 Y0\nG2 X10 Y0 R4.98\n",
            "line 2: an R arc no controller could cut: radius 4.98 mm, chord 10 mm, so R is "
            "0.02 mm short of half the chord, past the file's written precision of 0.01 mm");
    refused("G1 X0 Y0\nG41 D1 X5 Y5\n", "line 2: cutter radius compensation (G41)");
    refused("G1 X0 Y0\nG81 X5 Y5 Z-1\n", "line 2: canned cycle G81 without its R or Z");
    refused("G55\nG1 X1 Y1\n", "line 2: a move in G55, whose zero the controller holds");
    refused("o100 call\n", "line 1: o100 call: the subroutine is not in this file");
    refused("G1 X0 Y0\nG1 X[1+] Y0\n", "line 2:");
    refused("G1 X0 Y0\n/G1 X5 Y5\n", "line 2: a move under block delete");
    refused("G90.1\n", "line 1: absolute arc centres");
    refused("G1 X0 Y0\nG90 G1.55 X1 Y1\n", "line 2: bad command number after G");
    refused("G1 X0 Y0\nG1 X1 Y1 Q\"\n", "line 2: bad number");
}

namespace {

// The absolute XY positions an output job reaches, move by move (the test's own reading: G90 /
// G91, G20 / G21, G0 / G1 only, which is all compensate_gcode writes for motion).
std::vector<Point2> positions_of(const std::string& job) {
    std::vector<Point2> out;
    Point2 at;
    bool absolute = true;
    double unit = 1;
    for (const auto& raw : lines_of(job)) {
        const auto line = gcode::parse_line(raw);
        for (const int g : {20, 21, 90, 91}) {
            bool here = line.is('G', g);
            for (const auto& w : line.parameters)
                here = here || (w.letter == 'G' && w.value && *w.value == g);
            if (!here) continue;
            if (g == 20 || g == 21) unit = g == 20 ? 25.4 : 1;
            if (g == 90 || g == 91) absolute = g == 90;
        }
        if (!(line.is('G', 0) || line.is('G', 1))) continue;
        if (!line.has('X') && !line.has('Y')) continue;
        const double x = line.value('X').value_or(absolute ? at.x / unit : 0) * unit;
        const double y = line.value('Y').value_or(absolute ? at.y / unit : 0) * unit;
        at = absolute ? Point2{x, y} : Point2{at.x + x, at.y + y};
        out.push_back(at);
    }
    return out;
}

}  // namespace

TEST(Compensate, cutter_radius_compensation_writes_the_path_linuxcnc_cuts) {
    // A 10 mm square run anticlockwise, the cutter (6 mm across) on its left: inside it. Worked
    // by hand: the entry move up the left side ends 3 mm left of (0, 0); the turn along the bottom
    // is an outside corner for it (an arc about (0, 0) to (0, 3)); the three later corners are
    // inside ones, cut where the offset sides cross: (7, 3), (7, 7), (3, 7); G40 leaves the last
    // side at (3, 0), and the exit goes from there.
    // The same square in incremental distances (G91) cuts the same path.
    jobs::CompensateReport report;
    jobs::CompensateSettings s;
    s.max_segment_mm = 1000;
    const jobs::JobFrame frame{jobs::Flavour::linuxcnc, {Point2{}}, {}, {}};
    for (const std::string job :
         {"G21 G90 G17\nG0 X0 Y-10\nG41.1 D6\nG1 X0 Y0 F100\nX10 Y0\nX10 Y10\nX0 Y10\nX0 "
          "Y0\nG40\nG0 X0 Y-10\nM2\n",
          "G21 G90 G17\nG0 X0 Y-10\nG91 G41.1 D6\nG1 X0 Y10 F100\nX10 Y0\nX0 Y10\nX-10 Y0\n"
          "X0 Y-10\nG40\nG0 X0 Y-10\nG90\nM2\n"}) {
        const std::string out = jobs::compensate_gcode(job, {kIdentity, {}}, frame, s, report);
        const auto at = positions_of(out);
        const std::vector<Point2> corners{{0, -10}, {-3, 0}, {0, 3}, {7, 3},
                                          {7, 7},   {3, 7},  {3, 0}, {0, -10}};
        std::size_t next = 0;
        for (const auto& p : at) {
            if (next < corners.size() &&
                std::hypot(p.x - corners[next].x, p.y - corners[next].y) < 1e-6)
                ++next;
            else  // the arc's chords, between (-3, 0) and (0, 3): on the circle about (0, 0)
                CHECK_TEXT(next == 2 && std::abs(std::hypot(p.x, p.y) - 3) < 1e-3, out.c_str());
        }
        CHECK_TEXT(next == corners.size(), out.c_str());
        CHECK(out.find("G41") == std::string::npos);
    }

    // An arc: up from (0, -10) to (0, 0), then anticlockwise about (-10, 0) to (-10, 10), the
    // cutter (6 mm across) on the left, inside the arc. Worked by hand: the entry ends 3 mm left
    // of (0, 0), at (-3, 0), where the arc goes on tangent; the cutter's arc keeps 7 mm from
    // (-10, 0) and ends 3 mm inside the programmed end, at (-10, 7); G40's exit goes from there.
    {
        const std::string out = jobs::compensate_gcode(
            "G21 G90 G17\nG0 X0 Y-10\nG41.1 D6\nG1 X0 Y0 F100\nG3 X-10 Y10 I-10 J0\n"
            "G40\nG0 X-10 Y20\nM2\n",
            {kIdentity, {}}, frame, s, report);
        const auto at = positions_of(out);
        const std::vector<Point2> ends{{0, -10}, {-3, 0}, {-10, 7}, {-10, 20}};
        std::size_t next = 0;
        for (const auto& p : at) {
            if (next < ends.size() && std::hypot(p.x - ends[next].x, p.y - ends[next].y) < 1e-6)
                ++next;
            else  // the arc's chords, on the circle of 7 mm about (-10, 0)
                CHECK_TEXT(next == 2 && std::abs(std::hypot(p.x + 10, p.y) - 7) < 1e-3,
                           out.c_str());
        }
        CHECK_TEXT(next == ends.size(), out.c_str());
    }

    const auto refused = [&](const std::string& text, const std::string& words,
                             std::optional<double> radius = std::nullopt) {
        jobs::CompensateSettings r = s;
        r.tool_radius_mm = radius;
        try {
            jobs::compensate_gcode(text, {kIdentity, {}}, frame, r, report);
        } catch (const jobs::CompensateError& e) {
            const std::string what = e.what();
            CHECK_TEXT(what.find(words) != std::string::npos, what.c_str());
            return;
        }
        FAIL(("not refused: " + text).c_str());
    };
    // The tool table's radius is not in the file; given, the same path right of a reversed run.
    refused("G21 G90\nG0 X0 Y-10\nG42 D1\nG1 X0 Y0 F100\nG40\nM2\n",
            "line 3: cutter radius compensation (G41 / G42) by the controller's tool table: give "
            "the cutter's radius (calbox compensate --tool-radius MM)");
    refused("G21 G90\nG0 X0 Y0\nG41.1 D6\nG1 X2 Y0 F100\nM2\n",
            "line 4: the first move under cutter radius compensation is 2 long, not longer than "
            "the cutter's radius 3");
    refused("G21 G90\nG0 X0 Y-10\nG41.1 D6\nG1 X0 Y0 F100\nG3 X4 Y0 I2 J0\nM2\n",
            "line 5: an arc no larger than the cutter's radius with the cutter inside it");
    refused("G21 G90\nG0 X0 Y-10\nG41.1 D6\nG1 X0 Y0 F100\nG2 X10 Y0 I5 J0 P2\nM2\n",
            "line 5: an arc of more than one turn (P) under cutter radius compensation");
    refused("G21 G90\nG28\nG41.1 D6\nG1 X0 Y0 F100\nM2\n",
            "line 4: cutter radius compensation starts where the position is not known");
    refused("G21 G90\nG0 X0 Y-10\nG41.1 D6\nG1 X0 Y0 F100\nT2 M6\nM2\n",
            "line 5: a tool change under cutter radius compensation");
    // After the inside corner at (10, 0) the cutter (3 mm radius) starts up the right side at
    // (7, 3): the 1 mm move to (10, 1) would end at (7, 1), back down the side. LinuxCNC finds it
    // where the held move is next ended: at G40, at the program's end, at an outside corner.
    const std::string short_after_corner =
        "G21 G90\nG0 X-10 Y-10\nG41.1 D6\nG1 X0 Y0 F100\nG1 X10 Y0\nG1 X10 Y1\n";
    refused(short_after_corner + "M5\nG40\nM2\n",
            "line 8: a move the cutter would run backwards along (shorter than the inside corner "
            "before it takes back) (the move on line 6)");
    refused(short_after_corner + "M2\n", "line 7: a move the cutter would run backwards along");
    refused(short_after_corner + "G0 X20 Y1\nG40\nM2\n",
            "line 7: a move the cutter would run backwards along");
}

TEST(Compensate, modal_words_comments_and_program_delimiters_are_carried) {
    const std::string job =
        "%\nG21 G90 G17\nS12000 M3\nF500\nG1 X0 Y0\nX2 Y0\n; fill = *rect* ;\nM5\n%\n";
    const auto out = lines_of(compensated(job, [](Point2 p) { return Point2{p.x + 1, p.y}; }));
    CHECK_EQUAL(std::string("%"), out[0]);
    CHECK_EQUAL(std::string("S12000 M3"), out[2]);
    CHECK_EQUAL(std::string("F500"), out[3]);
    CHECK_EQUAL(std::string("G1 X1 Y0"), out[4]);
    // The modal move (X2 Y0 under G1) in two pieces through the correction.
    CHECK_EQUAL(std::string("G1 X2 Y0"), out[5]);
    CHECK_EQUAL(std::string("G1 X3 Y0"), out[6]);
    CHECK_EQUAL(std::string("; fill = *rect* ;"), out[7]);
    CHECK_EQUAL(std::string("%"), out[9]);
}

TEST(Compensate, inches_relative_moves_and_g92_offsets_are_tracked) {
    // 1 % long in x: a point x mm out lands at 1.01 x.
    const jobs::Correction longer = [](Point2 p) { return Point2{1.01 * p.x, p.y}; };
    // Inches: 1 in = 25.4 mm goes to 25.654 mm = 1.01 in, written in inches.
    const auto inches = lines_of(compensated("G20\nG90\nG0 X0 Y0\nG1 X1 Y0\n", longer));
    CHECK_EQUAL(std::string("G1 X1.01 Y0"), inches.back());
    CHECK_EQUAL(2u + 1u + 26u, inches.size());  // 25.4 mm in pieces of at most 1 mm
    // Relative moves: from x = 10 by 2 mm, the corrected end is 12.12, 0.12 past the start's
    // corrected 10.1 + 2; the pieces add up to it.
    const auto relative = positions_of(compensated("G90\nG0 X10 Y0\nG91\nG1 X2 Y1\n", longer));
    DOUBLES_EQUAL(12.12, relative.back().x, 1e-9);
    DOUBLES_EQUAL(1, relative.back().y, 1e-9);
    // G92 X0 at x = 10: the job's x = 5 is the frame's 15, corrected to 15.15: the job's 5.15.
    const auto offset = lines_of(compensated("G90\nG0 X10 Y0\nG92 X0 Y0\nG0 X5 Y0\n", longer));
    CHECK_EQUAL(std::string("G0 X5.15 Y0"), offset.back());
    // G92.1 clears it: x = 5 is the frame's 5 again.
    const auto cleared =
        lines_of(compensated("G90\nG0 X10 Y0\nG92 X0 Y0\nG92.1\nG0 X5 Y0\n", longer));
    CHECK_EQUAL(std::string("G0 X5.05 Y0"), cleared.back());
}

TEST(Compensate, arcs_in_every_plane_and_helices_are_traced) {
    // G18 (the ZX plane), clockwise as seen from +Y: from x = 0 to x = 10 about x = 5 it passes
    // z = -5 (worked by hand from the standard's axis order Z, X).
    const auto xz = lines_of(compensated("G90\nG0 X0 Y0 Z0\nG18\nG2 X10 Z0 I5 K0\n"));
    double lowest = 0;
    for (std::size_t i = 3; i < xz.size(); ++i) {
        const auto l = gcode::parse_line(xz[i]);
        const double x = *l.value('X'), z = *l.value('Z');
        DOUBLES_EQUAL(25, (x - 5) * (x - 5) + z * z, 0.01);
        DOUBLES_EQUAL(0, *l.value('Y'), 1e-9);
        lowest = std::min(lowest, z);
    }
    DOUBLES_EQUAL(-5, lowest, 0.01);
    // A helix: half a turn counter-clockwise about the origin, rising 2 mm.
    const auto helix = lines_of(compensated("G90\nG0 X5 Y0 Z0\nG3 X-5 Y0 Z2 I-5 J0\n"));
    for (std::size_t i = 2; i < helix.size(); ++i) {
        const auto l = gcode::parse_line(helix[i]);
        const double x = *l.value('X'), y = *l.value('Y'), z = *l.value('Z');
        DOUBLES_EQUAL(25, x * x + y * y, 0.01);
        CHECK(y >= -1e-9);
        // The height follows the angle swept.
        DOUBLES_EQUAL(2 * std::atan2(y, x) / 3.14159265358979, z, 0.001);
    }
    // G19 (the YZ plane) with J and K.
    const auto yz = lines_of(compensated("G90\nG0 X0 Y0 Z0\nG19\nG3 Y10 Z0 J5 K0\n"));
    for (std::size_t i = 3; i < yz.size(); ++i) {
        const auto l = gcode::parse_line(yz[i]);
        const double y = *l.value('Y'), z = *l.value('Z');
        DOUBLES_EQUAL(25, (y - 5) * (y - 5) + z * z, 0.01);
    }
}

TEST(Compensate, numbered_and_checksummed_lines_are_renumbered) {
    const auto out = lines_of(compensated("N10 G90\nN20 G0 X0 Y0\nN30 G1 X2 Y0 (cut)\nN40 M5\n"));
    CHECK_EQUAL(std::string("N10 G90"), out[0]);
    CHECK_EQUAL(std::string("N30 G1 X1 Y0"), out[2]);
    CHECK_EQUAL(std::string("N40 G1 X2 Y0 (cut)"), out[3]);
    CHECK_EQUAL(std::string("N50 M5"), out[4]);
    const std::string first = gcode::numbered_line(1, "G0 X0 Y0");
    const std::string second = gcode::numbered_line(2, "G1 X2 Y0");
    const auto host = lines_of(compensated(first + "\n" + second + "\n"));
    CHECK_EQUAL(3u, host.size());
    CHECK_EQUAL(gcode::numbered_line(3, "G1 X2 Y0"), host[2]);
    for (const auto& l : host) CHECK(gcode::parse_line(l).line_number.has_value());
}

TEST(Compensate, scanner_jobs_are_corrected_point_by_point) {
    jobs::CompensateReport report;
    const auto out = lines_of(jobs::compensate_scanner_csv("x_mm,y_mm,power\n0,0,0\n2,0,0.8\n",
                                                           {[](Point2 p) {
                                                                return Point2{p.x * 2, p.y};
                                                            },
                                                            {-10, -10, 1.5, 10}},
                                                           kMachineFrame, {}, report));
    CHECK_EQUAL(std::string("x_mm,y_mm,power"), out[0]);
    CHECK_EQUAL(std::string("0.0000,0.0000,0"), out[1]);
    CHECK_EQUAL(std::string("2.0000,0.0000,0.8"), out[2]);
    // Half a millimetre past the measured area: its edge's correction (+1.5 mm) held, not the
    // model's +2 mm there.
    CHECK_EQUAL(std::string("3.5000,0.0000,0.8"), out[3]);
    CHECK_EQUAL(1, report.held);
    DOUBLES_EQUAL(0.5, report.held_farthest_mm, 1e-12);
    CHECK_THROWS(jobs::CompensateError,
                 jobs::compensate_scanner_csv("x,y\n", {kIdentity, {}}, kMachineFrame, {}, report));
    CHECK_THROWS(jobs::CompensateError,
                 jobs::compensate_scanner_csv("x_mm,y_mm,power\n1,2,3\n", {kIdentity, {}},
                                              kMachineFrame, {}, report));
}

// The machine's error through a kept correction, worked out from a target made without it (what
// drift asks of a galvo or a router): hand-worked on a 10 mm square of four points.
#include "core/modes/error_through.hpp"

TEST_GROUP(ErrorThrough){};

TEST(ErrorThrough, a_correction_that_holds_leaves_nothing_and_one_that_does_not_leaves_the_rest) {
    using calbox::geometry::Point2;
    const std::vector<Point2> at{{-5, -5}, {5, -5}, {5, 5}, {-5, 5}};
    // The machine goes 1 % too far in x: each point lands 0.01 x off.
    std::vector<Point2> error;
    for (const auto& p : at) error.push_back({0.01 * p.x, 0});
    const calbox::jobs::Correction field = [](Point2 p) { return Point2{0.01 * p.x, 0}; };
    // The kept correction is that error's exact inverse: commanded at x / 1.01 it lands on x.
    const calbox::jobs::KeptCorrection exact{[](Point2 p) {
                                                 return Point2{p.x / 1.01, p.y};
                                             },
                                             -5, -5, 5, 5};
    const auto held = calbox::modes::error_through(at, error, exact, field);
    DOUBLES_EQUAL(0, held.rms_mm, 1e-12);
    // Without the field the error is taken where the point was meant, not where it is sent:
    // x / 1.01 + 0.01 x = 1.000099 x, 0.000099 * 5 mm off at every point.
    const auto first_order = calbox::modes::error_through(at, error, exact);
    DOUBLES_EQUAL(5 * (1 / 1.01 + 0.01 - 1), first_order.max_mm, 1e-12);
    // No correction (the identity): the raw error, less the rigid part (none here: a stretch).
    const calbox::jobs::KeptCorrection none{[](Point2 p) { return p; }, -5, -5, 5, 5};
    const auto raw = calbox::modes::error_through(at, error, none);
    DOUBLES_EQUAL(0.05, raw.max_mm, 1e-12);
    DOUBLES_EQUAL(0.05, *raw.mean_mm, 1e-12);
    // A shift of the whole work is where it lies, not an error: taken out.
    const calbox::jobs::KeptCorrection shifted{[](Point2 p) {
                                                   return Point2{p.x + 1, p.y};
                                               },
                                               -5, -5, 5, 5};
    DOUBLES_EQUAL(0.05, calbox::modes::error_through(at, error, shifted).max_mm, 1e-9);
    // Beyond the kept rectangle a point takes its edge's correction, as jobs do.
    const calbox::jobs::KeptCorrection smaller{[](Point2 p) {
                                                   return Point2{p.x / 1.01, p.y};
                                               },
                                               -4, -5, 4, 5};
    const auto edge = calbox::modes::error_through(at, error, smaller, field);
    // x = 5 is sent where x = 4 is moved: 5 + (4 / 1.01 - 4), and lands 1 % further than that.
    const double sent = 5 + 4 / 1.01 - 4, landed = 1.01 * sent;
    DOUBLES_EQUAL(landed - 5, edge.max_mm, 1e-9);
    CHECK_THROWS(std::invalid_argument,
                 calbox::modes::error_through({{0, 0}, {1, 1}}, {{0, 0}, {0, 0}}, none));
}
