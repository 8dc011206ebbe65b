#pragma once

// The words of a job's line as the compensator and the cutter's path read them: the G codes
// with their modal numbers, the M and T words in the order the controller acts on them, the
// comments kept after a line's last piece, numbers written as G-code writes them.

#include <string>
#include <string_view>
#include <vector>

#include "core/gcode/gcode_line.hpp"

namespace calbox::jobs::job_words {

// A number as G-code writes it: no exponent, no trailing zeros.
std::string number(double v, int decimals);

// A G word's number and its decimal (92.1 -> 92, 1; 90 -> 90, -1).
struct Code {
    int number = -1, subcode = -1;
    bool is(int n) const { return number == n && subcode < 0; }
    bool is_motion() const { return number >= 0 && number <= 3 && subcode < 0; }
    // Appended piece by piece: at -O3 (the release preset) GCC 12 takes `"G" + to_string(...)`
    // for an overlapping copy, and -Werror=restrict stopped the main job's build (GCC bug 105329).
    std::string text() const {
        std::string out = "G";
        out += std::to_string(number);
        if (subcode >= 0) {
            out += '.';
            out += std::to_string(subcode);
        }
        return out;
    }
};

// The line's G words: its command and every G among its words (G90 G94 G17 G21), read as the
// command is. Throws gcode::SyntaxError for a G word that is no command number.
std::vector<Code> g_codes_of(const gcode::Line& line);

// Whether the line holds an M word numbered from..to (its command or a word after it), in one look
// at its words (a job's every line asks).
bool has_m_in(const gcode::Line& line, int from, int to);
bool has_m(const gcode::Line& line, int number);

// Whether LinuxCNC refuses a centre-format arc whose end lies `step_mm` off the circle through
// its start (radius `radius_mm`), in a job written in inches or millimetres.
bool arc_end_off_its_circle(double radius_mm, double step_mm, bool inch_job);

// The axes beyond X Y Z: rotary A B C, linear U V W.
constexpr std::string_view kOtherAxes = "ABCUVW";

// The canned cycles' motion codes (G73, G81..G89).
bool is_cycle(int motion);

// The M and T words of a line as written, split by when the controller acts on them: a stop
// (M0, M1, M2, M30, M60) after the line's motion, the others before it.
struct CommandWords {
    std::string before, after;
};
CommandWords command_words(const gcode::Line& line);

// The line's comments, after its last piece: only the comments (words after an inline comment
// are the line's words, written already).
std::string trailing_comment(const std::string& raw);

// A line as the controller reads it: its words parsed, its G codes, whether it had polar words.
struct ReadLine {
    gcode::Line line;
    std::vector<Code> codes;
    bool polar = false;
};

// A move's line split as LinuxCNC acts on it: `head` what acts before its motion (its G codes
// but the motion and G40-G42, its F, S and T, its M words that are not stops), `tail` what
// follows its motion in X and Y (its Z, its stops, its comments). Words of the letters `taken_out`
// are left out; `other` is a letter beyond those ('\0' where none: a move with an A, a K or an H,
// say, is no such move).
struct MoveWords {
    std::string head, tail;
    char other = '\0';
};
MoveWords move_words(const std::string& raw, const ReadLine& r, std::string_view taken_out);

// The line rebuilt from its words: its number, its G codes but G41 / G42, its other words but
// D and the letters `drop`, then `extra` words, its M and T words and its comments. What remains
// of a line for the compensator once cutter radius compensation has been carried out.
std::string rebuilt_line(const std::string& raw, const ReadLine& r, const std::string& extra = {},
                         std::string_view drop = {});

}  // namespace calbox::jobs::job_words
