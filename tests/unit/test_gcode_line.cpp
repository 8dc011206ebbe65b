#include <CppUTest/TestHarness.h>

#include <cstdio>
#include <stdexcept>

#include "core/number_text.hpp"
#include "core/gcode/gcode_line.hpp"

using calbox::gcode::parse_line;
using calbox::gcode::SyntaxError;

TEST_GROUP(GcodeLine){};

TEST(GcodeLine, reads_command_and_parameters_in_any_case) {
    const auto l = parse_line("g1 x10.5 Y-2 e.25 F1200");
    CHECK(l.is('G', 1));
    DOUBLES_EQUAL(10.5, *l.value('X'), 0);
    DOUBLES_EQUAL(-2, *l.value('Y'), 0);
    DOUBLES_EQUAL(0.25, *l.value('E'), 0);
    DOUBLES_EQUAL(1200, *l.value('F'), 0);
    CHECK_FALSE(l.value('Z').has_value());
}

TEST(GcodeLine, strips_both_comment_styles) {
    const auto l = parse_line("G1 (move) X1 ; the rest Y9");
    CHECK(l.is('G', 1));
    CHECK(l.has('X'));
    CHECK_FALSE(l.has('Y'));
    CHECK_EQUAL(0, parse_line("; only a comment").command_letter);
    CHECK_EQUAL(0, parse_line("   ").command_letter);
}

TEST(GcodeLine, bare_flags_have_no_value) {
    const auto l = parse_line("G28 X Y");
    CHECK(l.is('G', 28));
    CHECK(l.has('X'));
    CHECK_FALSE(l.value('X').has_value());
}

TEST(GcodeLine, accepts_line_number_and_correct_checksum) {
    // XOR of the bytes of "N3 T0" is 57, as in the RepRap wiki's example.
    const auto l = parse_line("N3 T0*57");
    CHECK(l.is('T', 0));
    CHECK_EQUAL(3L, *l.line_number);
}

TEST(GcodeLine, rejects_wrong_checksum) {
    CHECK_THROWS(SyntaxError, parse_line("N3 T0*58"));
}

TEST(GcodeLine, rejects_bad_numbers_and_stray_text) {
    CHECK_THROWS(SyntaxError, parse_line("G1 X1.2.3"));
    CHECK_THROWS(SyntaxError, parse_line("G1 X1 #"));
    CHECK_THROWS(SyntaxError, parse_line("G1 (open comment X1"));
    CHECK_THROWS(SyntaxError, parse_line("G1.55 X1"));
    CHECK_THROWS(SyntaxError, parse_line("M3.5"));
    // Found by tests/fuzz (libFuzzer under UBSan): numbers past what a command or a line number
    // can be were converted to integers anyway.
    CHECK_THROWS(SyntaxError, parse_line("G233333333333333333333G1"));
    CHECK_THROWS(SyntaxError, parse_line("M10000"));
    CHECK_THROWS(SyntaxError, parse_line("N99999999999 G1 X1"));
    CHECK_THROWS(SyntaxError, parse_line("N-1 G1 X1"));
    CHECK_EQUAL(9999, parse_line("M9999").command_number);
    CHECK_EQUAL(2147483647L, *parse_line("N2147483647 G1").line_number);
}

TEST(GcodeLine, keeps_message_text) {
    const auto l = parse_line("M117 Printing X5 now");
    CHECK(l.is('M', 117));
    STRCMP_EQUAL("Printing X5 now", l.text.c_str());
    CHECK_FALSE(l.has('X'));
}

TEST(GcodeLine, reads_reprapfirmware_lists) {
    const auto l = parse_line("M665 L250.100:249.9:+251 R140 X-0.25");
    const auto rods = l.values('L');
    CHECK_EQUAL(3U, rods.size());
    DOUBLES_EQUAL(250.1, rods[0], 0);
    DOUBLES_EQUAL(249.9, rods[1], 0);
    DOUBLES_EQUAL(251, rods[2], 0);
    DOUBLES_EQUAL(250.1, *l.value('L'), 0);  // the first element
    CHECK_EQUAL(1U, l.values('R').size());
    CHECK(l.values('Y').empty());
    CHECK_THROWS(SyntaxError, parse_line("M665 L250::249"));
    CHECK_THROWS(SyntaxError, parse_line("M665 L250:"));
    CHECK_THROWS(SyntaxError, parse_line("M665 L:250"));
    CHECK_THROWS(SyntaxError, parse_line("N1:2 M665"));
    CHECK_THROWS(SyntaxError, parse_line("M665:1 L250"));
}

// As CAM writes it: modal words alone, '%' delimiters, block delete, a G code's decimal, a '*'
// inside a comment (PrusaSlicer's settings), which is text and not a checksum.
TEST(GcodeLine, reads_g_code_as_cam_and_slicers_write_it) {
    const auto modal = parse_line("S12000");
    CHECK_EQUAL(0, modal.command_letter);
    DOUBLES_EQUAL(12000, *modal.value('S'), 0);
    const auto axes = parse_line("X10 Y-2.5");
    DOUBLES_EQUAL(-2.5, *axes.value('Y'), 0);
    CHECK_EQUAL(0u, parse_line("%").parameters.size());
    CHECK_EQUAL(0, parse_line(" % ").command_letter);
    const auto deleted = parse_line("/G1 X1");
    CHECK(deleted.block_delete);
    CHECK(deleted.is('G', 1));
    const auto reset = parse_line("G92.1");
    CHECK_EQUAL(1, reset.command_subcode);
    CHECK(!reset.is('G', 92));
    CHECK_EQUAL(0u, parse_line("; infill_pattern = *gyroid*").parameters.size());
    CHECK_EQUAL(1u, parse_line("G1 X1 ; a*b").parameters.size());
    CHECK_EQUAL(1u, parse_line("G1 X1 (a*b)").parameters.size());
    CHECK_EQUAL(std::string("G1 X1 ; a*b"), std::string(calbox::gcode::without_checksum("G1 X1 ; a*b")));
    CHECK_EQUAL(std::string("N3 T0"), std::string(calbox::gcode::without_checksum("N3 T0*57")));
}

// A job's numbers are written by fixed_text: it must write what printf's "%.<n>f" writes, digit
// for digit (halves, negative zero, carries, large and tiny values), or a job's coordinates move.
TEST(GcodeLine, fixed_text_writes_what_printf_writes) {
    const double values[] = {0.0,      -0.0,     0.5,       1.5,       2.5,       -2.5,
                             0.00005,  -0.00005, 0.000049,  123.45675, -53.11349, 9.99995,
                             99999.99, 1e-300,   -1e-300,   1e15,      3.0e300,   0.1 + 0.2,
                             1.0 / 3,  -2.0 / 3, 17238.625, 4.0E-5,    -0.00004999999};
    for (const double v : values)
        for (int decimals = 0; decimals <= 8; ++decimals) {
            char expected[512];
            std::snprintf(expected, sizeof expected, "%.*f", decimals, v);
            STRCMP_EQUAL(expected, calbox::fixed_text(v, decimals).c_str());
        }
    CHECK_THROWS(std::invalid_argument, calbox::fixed_text(1e300, 200));
}
