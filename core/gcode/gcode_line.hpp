#pragma once
// One line of G-code as RepRap-family firmware reads it: optional line number, one command,
// its parameter words, an optional checksum, and comments in ';' or '(...)'.
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace calbox::gcode {

class SyntaxError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct Word {
    char letter = 0;              // upper case
    std::optional<double> value;  // empty for a bare flag such as the X in "G28 X"
    // RepRapFirmware's lists ("L250.1:250.3:249.9"): every element, `value` the first; empty
    // for a plain number (its one value is `value`: a word read is no allocation) and a bare
    // flag. Line::values gives every element either way.
    std::vector<double> list;
};

struct Line {
    std::optional<long> line_number;
    char command_letter = 0;  // 'G', 'M' or 'T'; 0 for a line with no command (modal words)
    int command_number = -1;
    int command_subcode = -1;   // the 1 of G92.1, the 2 of G38.2; -1 for a whole number
    bool block_delete = false;  // the line starts with '/': the operator's switch skips it
    std::vector<Word> parameters;
    std::string text;  // the free text of M117/M118

    // A whole-numbered command: G92.1 is not G92.
    bool is(char letter, int number) const {
        return command_letter == letter && command_number == number && command_subcode < 0;
    }
    bool has(char letter) const;
    std::optional<double> value(char letter) const;  // empty when absent or bare
    std::vector<double> values(char letter) const;   // empty when absent or bare
};

// A command number as written (92, 92.1): its whole part and its one decimal (-1 for none).
struct CommandNumber {
    int number = -1;
    int subcode = -1;
};
// Empty when `value` is none for `letter`: negative, 10000 or more (no firmware's command numbers
// reach it; Marlin's highest is M9xx), a decimal on an M or T, or more than one decimal.
std::optional<CommandNumber> command_number_of(char letter, double value);

// A job's lines, without their '\n' (a last line without one counts; nothing follows a final
// '\n'). Views into `job`.
std::vector<std::string_view> lines_of_job(std::string_view job);

// Removes comments ('(' to ')', ';' to the end of the line); throws SyntaxError for an unclosed
// '('. A line of only '%' (a program's start and end, as CAM writes them) is blank.
std::string strip_comments(std::string_view raw);
// The RepRap checksum: XOR of the bytes.
std::uint8_t checksum(std::string_view text);
// "N<number> <command>*<checksum>", as hosts send a line that the firmware must acknowledge.
std::string numbered_line(long number, std::string_view command);

// The part of a raw line before its checksum's '*', where that '*' is outside every comment (a
// '*' in a comment is text: PrusaSlicer's settings block has them).
std::string_view without_checksum(std::string_view raw);

// The words of a line as RS274NGC (LinuxCNC) and grbl read it: blanks outside comments count
// for nothing ("X 1 0 . 5" is X10.5), letters in either case, and after every letter a number
// with an optional sign and point, at least one digit and no exponent. `letters` are the ones the
// controller has. Returns the words upper case, one blank apart, without comments ('(...)' and
// ';' to the end), a leading '/' kept. Throws SyntaxError "column C: ..." naming the word.
std::string cnc_words(std::string_view raw, std::string_view letters);

// Every comment of a line ('(...)' and ';' to the end) in order, one blank apart: what is left
// of the line when its words are taken out.
std::string comments_of(std::string_view raw);

// Words before any command are modal (S12000, F500, X10 Y20 under the last motion command).
// Throws SyntaxError naming what is wrong (bad number, checksum mismatch, stray text).
Line parse_line(std::string_view raw);

}  // namespace calbox::gcode
