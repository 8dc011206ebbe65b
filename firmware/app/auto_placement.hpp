#pragma once
// `calbox run --board sim --auto` with a scenario's [placement]: after the cycle's verdict, stock
// lies on the bed where the box does not know it. A sheet (examples/router_stock.toml): the box
// photographs the bed, reads it through the set-up's camera and plane and the correction in
// force, finds the sheet's corner and compensates the job there (core/modes/stock,
// compensate_job: what `calbox view stock` and `calbox compensate --work-zero camera` do); the
// judge reads the twin's truth: where the router really drills each hole against where the job
// meant it on the sheet. A printed card (examples/laser_print_and_cut.toml): the box finds its
// registration marks and places the cut by them (`calbox view marks`, `compensate --register`);
// the judge runs the placed cut on the twin's machine against the line printed on the card.
#include <string>

#include "board/sim/sim_board.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

// Prints the placement's lines; writes the found sheet (placement-stock.json) or marks
// (placement-marks.json) and the placed job (placement-job-compensated.nc) into `data`. Throws
// std::runtime_error with one line when the box cannot place the job, or a hole or the cut misses
// the scenario's goal.
void judge_placement(const sim::TwinBench& bench, hal::Storage& data,
                     const std::string& kept_result_text);

}  // namespace calbox::firmware
