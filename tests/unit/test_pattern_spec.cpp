#include <CppUTest/TestHarness.h>

#include "core/geometry/pattern_spec.hpp"

using namespace calbox::geometry;

TEST_GROUP(PatternSpec){};

TEST(PatternSpec, reads_a_chessboard) {
    const auto p = parse_pattern_spec("chessboard:9x6@25.5");
    CHECK(p.kind == PatternSpec::Kind::chessboard);
    CHECK_EQUAL(9, p.columns);
    CHECK_EQUAL(6, p.rows);
    DOUBLES_EQUAL(25.5, p.square_mm, 0);
}

TEST(PatternSpec, reads_a_charuco_board) {
    const auto p = parse_pattern_spec("charuco:5x7@40/20:DICT_6X6_250");
    CHECK(p.kind == PatternSpec::Kind::charuco);
    CHECK_EQUAL(5, p.columns);
    CHECK_EQUAL(7, p.rows);
    DOUBLES_EQUAL(40, p.square_mm, 0);
    DOUBLES_EQUAL(20, p.marker_mm, 0);
    STRCMP_EQUAL("DICT_6X6_250", p.dictionary.c_str());
    CHECK_EQUAL(10, aruco_dictionary_id(p.dictionary));
}

TEST(PatternSpec, refuses_malformed_specs) {
    for (const char* bad :
         {"chessboard", "chessboard:9x6", "chessboard:9x@20", "chessboard:1x6@20",
          "chessboard:9x6@-3", "chessboard:9x6@abc", "dots:4x11@20", "aruco:4x3@30:DICT_4X4_50",
          "aruco:4x3@30/5", "charuco:5x7@40:DICT_6X6_250", "charuco:5x7@40/50:DICT_6X6_250",
          "charuco:5x7@40/20:DICT_9X9_1", "charuco:5x7@40/20"}) {
        CHECK_THROWS(PatternError, parse_pattern_spec(bad));
    }
}

TEST(PatternSpec, reads_marker_grids_and_dot_grids) {
    const auto a = parse_pattern_spec("aruco:4x3@30/6:DICT_4X4_50");
    CHECK(a.kind == PatternSpec::Kind::aruco);
    CHECK(a.has_markers());
    DOUBLES_EQUAL(30, a.marker_mm, 0);
    DOUBLES_EQUAL(6, a.gap_mm, 0);
    CHECK_EQUAL(0, aruco_dictionary_id(a.dictionary));
    const auto c = parse_pattern_spec("acircles:4x11@15");
    CHECK(c.kind == PatternSpec::Kind::acircles);
    CHECK(c.is_circles());
    CHECK_EQUAL(4, c.columns);
    DOUBLES_EQUAL(15, c.square_mm, 0);
    CHECK(parse_pattern_spec("circles:7x5@10").kind == PatternSpec::Kind::circles);
}
