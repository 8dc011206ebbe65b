#pragma once
// The twin's judge: how far the machine is off in the twin's truth, before a cycle and after it
// (`calbox run --auto`'s before/after lines and its exit status, with the mode's goal). One judge
// per kind of machine, one verdict shape; the machine's kind (board/sim/twin_kind) picks it.
// Never called by the box's side.
#include <memory>
#include <optional>
#include <string>

#include "board/sim/sim_board.hpp"
#include "core/jobs/compensate.hpp"
#include "core/modes/goal.hpp"

namespace calbox::sim {

struct TwinVerdict {
    modes::ErrorFigures figures;
    std::string line;  // as printed after "before: " or "after: "
};

class TwinJudge {
  public:
    virtual ~TwinJudge() = default;
    // The machine as it is now, a fresh job sent as commanded.
    virtual TwinVerdict before() const = 0;
    // After a cycle: the machine as it is now, the fresh job sent through `kept` when the box
    // keeps a correction (a galvo's table, a router's model). Throws when a kind that needs one
    // has none.
    virtual TwinVerdict after(const std::optional<jobs::KeptCorrection>& kept) const = 0;
};

std::unique_ptr<TwinJudge> make_twin_judge(const TwinBench& bench);

}  // namespace calbox::sim
