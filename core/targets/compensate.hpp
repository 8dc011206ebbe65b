#pragma once
// Jobs compensated for a machine's measured error: every XY position a job commands goes through
// a correction (X_c = correct(X)), moves are split so that the correction follows the error
// field along them, and arcs become the straight moves that trace them. Everything else in the
// job (other words, comments, blank lines) is kept as written.
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "core/geometry/types.hpp"

namespace calbox::targets {

class CompensateError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct CompensateSettings {
    // Moves are split into pieces no longer than this, so that a correction that changes along
    // a move is followed within (piece length)^2 / 8 times its curvature.
    double max_segment_mm = 1.0;
    // Arcs are traced by chords that stray at most this far from the arc.
    double arc_tolerance_mm = 0.002;
};

struct CompensateReport {
    long lines = 0;    // lines read
    long moves = 0;    // moves whose XY went through the correction
    long pieces = 0;   // moves written after splitting
    long arcs = 0;     // G2 / G3 traced by straight moves
    long outside = 0;  // points the correction does not cover (continued from its edge)
};

using Correction = std::function<geometry::Point2(geometry::Point2)>;
using Covers = std::function<bool(geometry::Point2)>;

// A correction a box keeps and sends jobs through, with the rectangle it holds over.
struct KeptCorrection {
    Correction correct;
    double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
};

// G-code in absolute XY (G90), millimetres (G21). Throws CompensateError("line N: ...") for what
// it cannot carry through faithfully: relative XY moves (G91), inches (G20), G92 with X or Y,
// arcs off the XY plane (G18, G19), numbered or checksummed lines, or a syntax error.
std::string compensate_gcode(std::string_view job, const Correction& correct, const Covers& covers,
                             const CompensateSettings& settings, CompensateReport& report);

// The plain scanner job ("x_mm,y_mm,power" lines after that header; power 0 jumps, more marks):
// each point corrected, marked lines split like moves.
std::string compensate_scanner_csv(std::string_view job, const Correction& correct,
                                   const Covers& covers, const CompensateSettings& settings,
                                   CompensateReport& report);

}  // namespace calbox::targets
