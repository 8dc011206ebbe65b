#pragma once
// `calbox run --board sim --auto` with a scenario's [placement] (examples/router_stock.toml):
// after the cycle's verdict, a sheet of stock lies on the spoilboard where the box does not know
// it. The box's part is the owner's: the bed photographed, read through the set-up's camera and
// plane and the correction in force, the sheet's corner found and the job compensated there
// (core/modes/stock, compensate_job: what `calbox view stock` and `calbox compensate --work-zero
// camera` do). The judge's part reads the twin's truth: where the router really drills each hole
// against where the job meant it on the sheet.
#include <string>

#include "board/sim/sim_board.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

// Prints the placement's lines; writes the found sheet (placement-stock.json) and the placed job
// (placement-job-compensated.nc) into `data`. Throws std::runtime_error with one line when the
// box cannot place the job or a hole misses the scenario's goal.
void judge_placement(const sim::TwinBench& bench, hal::Storage& data,
                     const std::string& kept_result_text);

}  // namespace calbox::firmware
