#pragma once
// Executes a G-code job on a simulated machine and records every stroke of material (or laser
// mark, or cut) where the machine really put it.
#include <istream>
#include <stdexcept>
#include <string>
#include <vector>

#include "board/sim/machine_twin.hpp"

namespace calbox::sim {

class JobError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};
// A line the machine could not carry out (a move beyond its reach), not one it could not read.
class JobMachineError : public JobError {
  public:
    explicit JobMachineError(const std::string& what, int alarm = 2)
        : JobError(what), grbl_alarm(alarm) {}
    // What grbl says of it: 2, a move beyond the soft limits; 4 and 5, a probing cycle's
    // (ProbeAlarm).
    int grbl_alarm;
};

enum class ToolKind { extruder, laser, spindle };

struct ToolSettings {
    ToolKind kind = ToolKind::extruder;
    double filament_diameter_mm = 1.75;  // extruder
    double layer_height_mm = 0.2;        // extruder: the height a stroke's volume spreads over
    double tool_width_mm = 0.1;          // laser spot or cutter width
    double segment_mm = 0.5;             // moves are split as a delta firmware segments them
    // extruder: the first layer as a real one lies (first_layer_strand) rather than at its
    // commanded width with its top at the nozzle
    bool real_first_layer = true;
    double nozzle_flat_mm = 1.0;  // the nozzle tip's flat: a squashed strand spreads no wider
};

// A first-layer strand's cross-section as the nozzle leaves it: while the nozzle touches the
// strand (a gap under the strand's own size) it is pressed to the gap's height and spreads to
// keep its cross-section; past that it is a free bead of its own diameter lying on the bed
// (sqrt(4 A / pi)), no lower for a larger gap; where the nozzle meets the bed it scrapes a thin
// trace no wider than the tip's flat (the rest stays in the nozzle). Widths are the
// cross-section over the height: a rectangle of the strand's footprint.
struct StrandShape {
    double height_mm = 0;  // its top above the bed
    double width_mm = 0;
    bool free_bead = false;
};
StrandShape first_layer_strand(double cross_section_mm2, double gap_mm, double nozzle_flat_mm);

struct Stroke {
    Vec3 commanded_a_mm, commanded_b_mm;
    Vec3 a_mm, b_mm;  // where the nozzle/tool really was (machine frame, bed at z = 0)
    double width_mm = 0;
    int line = 0;  // job line number, from 1
    // The top of what was laid above the bed at each end: the nozzle's height, except for a
    // real first layer's free bead (first_layer_strand).
    double top_a_mm = 0, top_b_mm = 0;
};

struct JobResult {
    std::vector<Stroke> strokes;
    std::vector<std::string> replies;  // what the machine answered (M503 reports and the like)
    int lines_run = 0;
};

class GcodeRunner {
  public:
    GcodeRunner(MachineTwin& machine, const ToolSettings& tool);
    // Throws JobError("line N: ...") for a syntax error, an unknown command, a move out of
    // reach or a move before homing.
    void run_line(std::string_view text);
    void run(std::istream& job);
    const JobResult& result() const { return result_; }
    // The strokes laid so far are gone (the bed cleared): a twin that runs for hundreds of cycles
    // does not keep every one it ever laid.
    void forget_strokes() { result_.strokes.clear(); }

  private:
    void move(const gcode::Line& line);
    void execute(const gcode::Line& line);
    // grbl's `G53 G0|G1 X Y Z`: a move to machine coordinates, this line only.
    void move_in_machine_coordinates(const gcode::Line& line);
    // grbl's `G38.2 Z F`: down until the probe touches, reported as `[PRB:x,y,z:1]` (machine
    // coordinates).
    void probe(const gcode::Line& line);

    MachineTwin& machine_;
    ToolSettings tool_;
    JobResult result_;
    int line_number_ = 0;
    bool absolute_xyz_ = true;
    bool absolute_e_ = true;
    bool tool_on_ = false;
    Vec3 logical_{};  // position in the job's coordinates
    Vec3 offset_{};   // G92: machine = logical + offset
    double e_ = 0;    // extruder position as the job sees it
};

}  // namespace calbox::sim
