#pragma once
// Jobs compensated for a machine's measured error, where the machine really is: every XY position
// a job commands is placed on the machine (its work zero and offsets applied), refused beyond the
// travel, and goes through the correction (held at the measured area's edge beyond it); moves
// are split so that the correction follows the error field along them, arcs become the straight
// moves that trace them, canned cycles keep their holes. Everything else in the job (other
// words, comments, blank lines) is kept as written.
#include <array>
#include <cstddef>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/jobs/ngc_program.hpp"

namespace calbox::jobs {

class CompensateError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Which controller runs the job: what its words mean where controllers differ (G10, canned
// cycles). Printers (Marlin, RepRapFirmware, Klipper) take G10 / G11 as firmware retraction;
// grbl has no canned cycles, so the compensator writes them out as moves; LinuxCNC runs them.
enum class Flavour { printer, grbl, linuxcnc };
// The machine file's firmware ("marlin", "rrf", "klipper", "grbl", "linuxcnc"); throws
// CompensateError for another.
Flavour flavour_of_firmware(std::string_view firmware);

// A rectangle of the machine's XY, in machine coordinates.
struct Area {
    double min_x_mm = -1e300, min_y_mm = -1e300, max_x_mm = 1e300, max_y_mm = 1e300;
    bool contains(geometry::Point2 p) const;
    geometry::Point2 nearest(geometry::Point2 p) const;  // p itself when inside
};

// The work coordinate systems a job may select: G54..G59, then LinuxCNC's G59.1..G59.3.
constexpr std::size_t kWorkSystems = 9;

// Where a job's points are on the machine: the machine coordinates of each work system's zero
// that is known (a job that moves in one that is not is refused), and the machine's travel
// (a point beyond it is refused).
struct JobFrame {
    Flavour flavour = Flavour::printer;
    std::array<std::optional<geometry::Point2>, kWorkSystems> work_zero_mm{geometry::Point2{}};
    Area travel_mm;
    // Where the tool stands when the job starts, in machine coordinates, where the owner says:
    // a job that sets G92 before its first move says the tool is there.
    std::optional<geometry::Point2> start_mm;
    // A job placed turned about G54's zero (the camera found the stock turned): the point the
    // job means at zero + (x, y) goes to zero + R (x, y) before the correction, and the written
    // X Y are that point's command in G54 as the controller holds it (no rotation of its own).
    // Such a job keeps to G54 as the frame gives it: G10, G92 and other work systems are refused.
    double turn_rad = 0;
    // With the turn, a drawing's stretch as printed (print and cut): zero + scale R (x, y).
    double scale = 1;
};

struct CompensateSettings {
    // Moves are split into pieces no longer than this, so that a correction that changes along
    // a move is followed within (piece length)^2 / 8 times its curvature.
    double max_segment_mm = 1.0;
    // Arcs are traced by chords that stray at most this far from the arc.
    double arc_tolerance_mm = 0.002;
    // LinuxCNC's language: runaway loops and recursion stop here.
    gcode::ProgramLimits program;
    // The cutter's radius, mm, for a LinuxCNC job's cutter radius compensation by the tool table
    // (G41 / G42 D<tool>): the controller's table is not in the file. G41.1 / G42.1 give their
    // diameter on the line and need none.
    std::optional<double> tool_radius_mm;
};

struct CompensateReport {
    long lines = 0;               // lines read
    long moves = 0;               // moves whose XY went through the correction
    long pieces = 0;              // moves written after splitting
    long arcs = 0;                // G2 / G3 traced by straight moves
    long holes = 0;               // canned-cycle holes placed through the correction
    long held = 0;                // points outside the measured area, given its edge's correction
    double held_farthest_mm = 0;  // the farthest of them from the measured area
    bool ran_program = false;     // LinuxCNC's parameters, expressions or O-words evaluated
    // Asked for with keep_path: every point the tool is sent to, in order, in machine coordinates
    // where the job means it (before the correction), travel included: to draw the job on the bed.
    bool keep_path = false;
    std::vector<geometry::Point2> path_mm;
};

using Correction = std::function<geometry::Point2(geometry::Point2)>;

// A correction in machine coordinates: where to command so that the tool lands on a point. It
// is used only inside the measured area: a point beyond takes the correction of the area's
// nearest point (held at the edge, never extrapolated).
struct MachineCorrection {
    Correction correct;
    Area measured_mm;
};

// A correction a box keeps and sends jobs through, with the rectangle it holds over.
struct KeptCorrection {
    Correction correct;
    double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
};

// G-code as slicers, CAM and LinuxCNC write it: absolute or relative, millimetres or inches,
// G92 and work offsets tracked, arcs and helices traced, canned cycles' holes placed, LinuxCNC's
// parameters, expressions, O-words and polar words evaluated, LinuxCNC's cutter radius
// compensation of straight moves written out as the path it cuts. Throws CompensateError("line
// N: ...") naming the word and what to do for what it cannot carry through faithfully: cutter
// radius compensation elsewhere (arcs, G91, grbl, printers), a lathe job, an arc no controller
// could cut, a point beyond the travel, a move in a work system whose zero is not known.
std::string compensate_gcode(std::string_view job, const MachineCorrection& correction,
                             const JobFrame& frame, const CompensateSettings& settings,
                             CompensateReport& report);

// The plain scanner job ("x_mm,y_mm,power" lines after that header; power 0 jumps, more marks):
// each point corrected (in G54's frame), marked lines split like moves.
std::string compensate_scanner_csv(std::string_view job, const MachineCorrection& correction,
                                   const JobFrame& frame, const CompensateSettings& settings,
                                   CompensateReport& report);

// A compensated job's first line (after a leading '%'), naming the result it went through, so
// that it is never compensated twice.
std::string compensated_mark(std::string_view result_digest, std::string_view date);
// The mark's text when `job` carries one ("" when not).
std::string compensated_mark_in(std::string_view job);
// `job` with its mark added (a '#' comment for the scanner job, ';' for G-code).
std::string with_compensated_mark(std::string_view job, std::string_view mark);

}  // namespace calbox::jobs
