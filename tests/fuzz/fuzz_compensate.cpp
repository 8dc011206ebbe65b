// Fuzz target: a job through the correction (calbox compensate), as a printer's, grbl's or
// LinuxCNC's (the first byte chooses, and whether the correction warps or holds still). It may
// refuse a job only with CompensateError, and a job it takes comes out as lines its machine
// reads. Whether the written job moves as
// the original does is LinuxCNC's rs274 to judge (tests/cli/rs274_judge.py, its slow label).
#include <array>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "core/jobs/compensate.hpp"
#include "core/gcode/gcode_line.hpp"
#include "tests/fuzz/fuzz_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using calbox::geometry::Point2;
    namespace jobs = calbox::jobs;
    if (size == 0) return 0;
    const std::uint8_t choice = data[0];
    const std::string_view job = calbox::fuzz::as_text(data + 1, size - 1);
    jobs::JobFrame frame;
    frame.flavour = std::array{jobs::Flavour::printer, jobs::Flavour::grbl,
                               jobs::Flavour::linuxcnc}[choice % 3];
    frame.work_zero_mm = {};
    frame.work_zero_mm[0] = Point2{0, 0};      // G54
    frame.work_zero_mm[1] = Point2{-120, 35};  // G55; the others unknown: a move there is refused
    // A travel, so that a mutated number (X9e9) is refused, not split into billions of pieces.
    frame.travel_mm = {-500, -500, 500, 500};
    jobs::MachineCorrection correction;
    if ((choice / 3) % 2 == 0) {
        correction.correct = [](Point2 p) { return p; };
    } else {
        correction.correct = [](Point2 p) {
            return Point2{p.x + 1e-3 * p.y + 0.02, p.y - 1e-3 * p.x - 0.03};
        };
        correction.measured_mm = {-200, -150, 200, 150};  // beyond: held at the edge
    }
    jobs::CompensateSettings settings;
    settings.program.max_loop_turns = 10'000;
    settings.program.max_executed_lines = 100'000;
    jobs::CompensateReport report;
    std::string out;
    try {
        out = jobs::compensate_gcode(job, correction, frame, settings, report);
    } catch (const jobs::CompensateError&) {
        return 0;
    }
    // Each line as the machine it is for reads it: a printer's by the box's line reader (its link
    // parses every line it sends), a CNC controller's by the words it takes (blanks count for
    // nothing there: "L2 0" is L20).
    const std::string_view cnc_letters = frame.flavour == jobs::Flavour::linuxcnc
                                             ? "ABCDFGHIJKLMNPQRSTUVWXYZ"
                                             : "ABCDFGHIJKLMNPQRSTXYZ";
    for (const auto line : calbox::gcode::lines_of_job(out)) {
        try {
            if (frame.flavour == jobs::Flavour::printer)
                calbox::gcode::parse_line(line);
            else
                calbox::gcode::cnc_words(line, cnc_letters);
        } catch (const calbox::gcode::SyntaxError& e) {
            std::fprintf(stderr, "compensate wrote a line its machine refuses: '%.*s': %s\n",
                         static_cast<int>(line.size()), line.data(), e.what());
            std::abort();
        }
    }
    return 0;
}
