// Compensated jobs: every XY through the correction, moves split, arcs traced, the rest kept.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "core/targets/compensate.hpp"
#include "core/targets/gcode_line.hpp"

using namespace calbox;
using geometry::Point2;

namespace {

const targets::Correction kIdentity = [](Point2 p) { return p; };
const targets::Covers kEverywhere = [](Point2) { return true; };

std::vector<std::string> lines_of(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) out.push_back(l);
    return out;
}

std::string compensated(const std::string& job, const targets::Correction& c = kIdentity,
                        double segment = 1.0) {
    targets::CompensateReport report;
    targets::CompensateSettings s;
    s.max_segment_mm = segment;
    return targets::compensate_gcode(job, c, kEverywhere, s, report);
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
        } catch (const targets::CompensateError& e) {
            const std::string what = e.what();
            CHECK_TEXT(what.find(words) != std::string::npos, what.c_str());
            return;
        }
        FAIL(("not refused: " + job).c_str());
    };
    refused("G90\nG91\nG1 X1 Y1\n", "line 3: relative XY moves");
    refused("G20\n", "line 1: inches");
    refused("G92 X0 Y0\n", "line 1: G92");
    refused("N1 G1 X1 Y1\n", "line 1: numbered");
    refused("G1 X1\n", "line 1: a move that gives one axis");
    refused("G1 X0 Y0\nG18\n", "line 2: arcs off the XY plane");
    refused("G1 X0 Y0\nG2 X10 Y0 R4\n", "shorter than half its chord");
}

TEST(Compensate, scanner_jobs_are_corrected_point_by_point) {
    targets::CompensateReport report;
    const auto out = lines_of(targets::compensate_scanner_csv(
        "x_mm,y_mm,power\n0,0,0\n2,0,0.8\n",
        [](Point2 p) {
            return Point2{p.x * 2, p.y};
        },
        [](Point2 p) { return p.x < 1.5; }, {}, report));
    CHECK_EQUAL(std::string("x_mm,y_mm,power"), out[0]);
    CHECK_EQUAL(std::string("0.0000,0.0000,0"), out[1]);
    CHECK_EQUAL(std::string("2.0000,0.0000,0.8"), out[2]);
    CHECK_EQUAL(std::string("4.0000,0.0000,0.8"), out[3]);
    CHECK_EQUAL(1, report.outside);
    CHECK_THROWS(targets::CompensateError,
                 targets::compensate_scanner_csv("x,y\n", kIdentity, kEverywhere, {}, report));
    CHECK_THROWS(targets::CompensateError,
                 targets::compensate_scanner_csv("x_mm,y_mm,power\n1,2,3\n", kIdentity, kEverywhere,
                                                 {}, report));
}
