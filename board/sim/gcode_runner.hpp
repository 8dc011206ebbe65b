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

enum class ToolKind { extruder, laser, spindle };

struct ToolSettings {
    ToolKind kind = ToolKind::extruder;
    double filament_diameter_mm = 1.75;  // extruder
    double layer_height_mm = 0.2;        // extruder: the height a stroke's volume spreads over
    double tool_width_mm = 0.1;          // laser spot or cutter width
    double segment_mm = 0.5;             // moves are split as a delta firmware segments them
};

struct Stroke {
    Vec3 commanded_a_mm, commanded_b_mm;
    Vec3 a_mm, b_mm;  // where the nozzle/tool really was (machine frame, bed at z = 0)
    double width_mm = 0;
    int line = 0;  // job line number, from 1
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
