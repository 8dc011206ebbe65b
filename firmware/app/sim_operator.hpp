#pragma once
// The person at a sim board, for `calbox run --auto` and the tests: does what each prompt asks
// on the twin's bench (holds the board, lays it on the bed, clears the bed) and presses the
// button. Review is confirmed when `confirm_review` (else it is left to the button, the
// console or a PLC); the start and error prompts are left to the caller. With `press` false the
// person only does what is asked and leaves every press to the console (its tests).
#include "board/sim/sim_board.hpp"
#include "firmware/cycle/cycle.hpp"

namespace calbox::firmware {

inline bool act_on_prompt(sim::TwinBench& bench, sim::SimLines& lines, Prompt prompt, int step,
                          bool confirm_review = true, bool press = true) {
    switch (prompt) {
        case Prompt::hold_calibration_board:
            bench.hold_calibration_board(step);
            break;
        case Prompt::lay_plane_board:
            bench.lay_plane_board_on_bed();
            break;
        case Prompt::clear_bed:
            bench.take_board_away();
            bench.clear_bed();
            break;
        case Prompt::review:
            if (!confirm_review) return false;
            break;
        default:
            return false;
    }
    if (press) lines.press(std::chrono::milliseconds(100));
    return press;
}

}  // namespace calbox::firmware
