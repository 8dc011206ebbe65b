#pragma once

#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/jobs/job_words.hpp"

namespace calbox::jobs {

// A job's lines, each with its number in the file (for a refusal).
using JobLines = std::vector<std::pair<std::string, long>>;
// Reads a line (its number for a refusal), throwing gcode::SyntaxError for one that does not.
using ReadJobLine = std::function<job_words::ReadLine(const std::string&, long)>;

// Cutter radius compensation as LinuxCNC's interpreter carries it out (its "new" compensation:
// interp_convert.cc), for straight moves in G17 under G90: the job rewritten with the path the
// controller would cut, so that the compensator corrects that path. G41 / G42 put the cutter
// left / right of the programmed path, G41.1 / G42.1 with their diameter (D) on the line, G40
// ends it. The first move after them ends a radius off its programmed end, square to the move;
// each later move is offset by the radius; an outside corner is rounded by an arc about the
// programmed corner (a traverse straight across it for G0), an inside corner is cut where the
// two offset paths cross, the moves already held for it (a move, the height changes after it)
// pulled back there; what lies between moves (spindle, coolant, comments) keeps its order. A
// job this cannot carry faithfully is refused naming its line: an arc, G91, another plane, an
// offset or machine move, a canned cycle under compensation; an entry move no longer than the
// radius and a corner the tool cannot reach, as LinuxCNC refuses them.
// Throws CompensateError("line N: ...") for what it refuses; a line `read` cannot read is passed
// on as written, for the compensator to refuse naming its column.
JobLines cutter_path(const JobLines& lines, std::optional<double> tool_radius_mm,
                     const ReadJobLine& read);

}  // namespace calbox::jobs
