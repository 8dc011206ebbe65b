#pragma once
// What the cutter path (cutter_path.cpp) refuses under LinuxCNC's cutter radius compensation
// (G41, G42), and what it reads off a line to decide: each refusal one line, as the owner reads
// it; "" where the line passes.
#include <string>

#include "core/jobs/job_words.hpp"

namespace calbox::jobs::cutter_rules {

// `what` under compensation is not carried through: the refusal's text.
std::string refusal(const std::string& what);

// An offset, a machine-coordinate move or a return home: the position after it is another
// frame's.
bool reframes_position(const job_words::ReadLine& r);

// G41 or G41.1 on the line: 1 (left); else G42 or G42.1: -1 (right); else 0.
int compensation_turned_on(const job_words::ReadLine& r);

// A change of units, of the tool length offset or of the path control mode: LinuxCNC refuses
// each under compensation.
std::string mode_change_refusal(const job_words::ReadLine& r);

// An arc's words under compensation (`moves`: it moves an axis).
std::string arc_words_refusal(const gcode::Line& l, bool moves);

}  // namespace calbox::jobs::cutter_rules
