#pragma once
// An NGC line as LinuxCNC's interpreter reads it before it runs it: its comments apart, its
// O-word (the label and the keyword of a subroutine, a loop or a branch), names as it compares
// them. The program's runner (ngc_program.cpp) is built on these.
#include <optional>
#include <string>
#include <string_view>

namespace calbox::gcode::ngc {

char upper(char c);
bool is_blank(char c);

// The body of a line: comments removed ('(' to ')', ';' to the end), kept beside it.
struct SplitLine {
    std::string code;
    std::string comment;  // every comment of the line, as written
};

// Throws ProgramError for a '(' comment the line does not close.
SplitLine split_comments(std::string_view raw, long number);

// A number as plain G-code writes it: no exponent, trailing zeros dropped; ten decimals keep a
// computed value far finer than any machine's resolution.
std::string plain_number(double v);

// An O-word line: its label ("100", "<name>" lower-cased) and keyword, and what follows it.
struct OWord {
    std::string label;
    std::string keyword;
    std::string rest;
};

// Parameter names are read as LinuxCNC reads them: case and blanks do not count.
std::string normal_name(std::string_view name);

// The line's O-word; nothing for a line without one or a bare O number (Fanuc's "O1234").
std::optional<OWord> o_word_of(const std::string& code);

}  // namespace calbox::gcode::ngc
