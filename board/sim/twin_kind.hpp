#pragma once
// What the twin does differently for each kind of machine: the hidden truth its scenario gives
// ([truth.<table>]), the machine twin that runs the jobs, the judge of its error, and how its work
// looks on the bed. twin_kind_of is the one place on the twin's side that reads the machine's
// kind (its counterpart on the box's side is firmware's make_cycle_mode).
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/router_twin.hpp"
#include "board/sim/scenario.hpp"
#include "core/jobs/compensate.hpp"

namespace calbox::sim {

class TwinBench;
class TwinJudge;
struct TruthTable;  // a scenario's [truth.*] table as its reader has it (board/sim/truth_table.hpp)

// `calbox sim verify`: the twin's verdict on a solve's result file (or on the machine as it is),
// printed lines and a JSON record.
struct SimVerification {
    std::vector<std::string> lines;
    std::string json;
};
struct ResultFile {
    std::string path, text;
};

class TwinKind {
  public:
    virtual ~TwinKind() = default;
    // The [truth.*] table this kind reads; another kind's is refused.
    virtual const char* truth_table() const = 0;
    // Reads `table` (null: not given) into the scenario's truth, after the machine file's part.
    virtual void read_truth(const std::string& path, const TruthTable* table,
                            Scenario& s) const = 0;
    virtual std::unique_ptr<MachineTwin> make_machine(const Scenario& s) const = 0;
    virtual std::unique_ptr<TwinJudge> make_judge(const TwinBench& bench) const = 0;
    // What the machine works with: an extruder, a laser, a spindle.
    virtual ToolKind tool() const = 0;
    // A planar machine's judge in its truth: a fresh job half a pitch off the target's, as
    // commanded and (with `correct`) through the correction. Others throw ScenarioError.
    virtual RouterVerdict judge_fresh_job(const Scenario& s, const jobs::Correction* correct) const;
    // `calbox sim verify`: a fresh job in the twin's truth, as commanded and through `result`.
    virtual SimVerification verify(const Scenario& s,
                                   const std::optional<ResultFile>& result) const = 0;
    // What the camera sees of the strokes the machine made (a router's: holes in the sheet).
    virtual std::vector<StrokeSegment> on_the_bed(const Scenario&,
                                                  std::vector<StrokeSegment> strokes) const {
        return strokes;
    }
};

// Throws ScenarioError for a kind the twin does not know.
const TwinKind& twin_kind_of(const models::MachineFile& machine);
// The [truth.*] tables the twins read (a scenario's other parts are refused).
std::set<std::string> truth_table_names();

}  // namespace calbox::sim
