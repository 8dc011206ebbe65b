#pragma once
// The appliance on the sim board, wired as `calbox run` wires it: the board's devices, the data
// directory, the event loop, the worker, the machine link and the cycle. The clock is the
// caller's: the real one for `calbox run` and `calbox revert`, a fake one in the tests.
#include "board/sim/sim_board.hpp"
#include "drivers/file_storage.hpp"
#include "firmware/cycle.hpp"
#include "firmware/event_loop.hpp"
#include "firmware/gcode_host.hpp"

namespace calbox::firmware {

struct SimAppliance {
    sim::SimBoard board;
    drivers::FileStorage data;
    EventLoop loop;
    Worker worker{loop};
    GcodeHost host;
    Cycle cycle;

    SimAppliance(const sim::SimSettings& sim, hal::Clock& clock, GcodeHostSettings link,
                 CycleSettings settings, const Cycle::Log& log)
        : board(sim::make_sim_board(sim, clock, log)),
          data(sim.data_dir),
          host(*board.machine, clock, link, log),
          cycle({*board.camera, *board.lines, host, *board.display, clock, data, worker},
                board.bench->scenario().machine, std::move(settings), log) {
        watch_cycle(loop, cycle, host, *board.camera, *board.lines);
    }
    SimAppliance(const SimAppliance&) = delete;
    SimAppliance& operator=(const SimAppliance&) = delete;
    ~SimAppliance() { loop.unwatch(host.port_fd()); }
};

}  // namespace calbox::firmware
