#pragma once
// LinuxCNC's G-code language (rs274ngc) run as LinuxCNC's interpreter runs it, into the plain
// G-code lines it would execute: numbered, named and global parameters, expressions with its
// operators and functions, and O-word subroutines, loops and conditionals. Polar words (@, ^)
// are left for the compensator, which knows the position they are taken from.
#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace calbox::gcode {

class ProgramError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct ProgramLimits {
    // A loop that runs longer, or a program that executes more lines, is taken for runaway input
    // (LinuxCNC's own sample programs run a few hundred thousand lines).
    long max_loop_turns = 1'000'000;
    long max_executed_lines = 5'000'000;
    int max_call_depth = 50;  // LinuxCNC's own limit on nested calls
};

struct ExecutedLine {
    std::string text;  // plain G-code: every parameter and expression replaced by its value
    long source_line = 0;
};

// True when `job` uses the language beyond plain words: '#', '[ ]' or O-words outside comments.
bool uses_ngc_language(std::string_view job);

// The lines LinuxCNC would execute, in order, up to and including M2 / M30 (the program's end).
// A line without parameters or expressions is passed on as written. Throws ProgramError
// ("line N: ...") for what LinuxCNC would refuse (an unknown named parameter, an unmatched O-word,
// a call of a subroutine in another file) and for a loop or program past `limits`.
std::vector<ExecutedLine> run_ngc_program(std::string_view job, const ProgramLimits& limits = {});

}  // namespace calbox::gcode
