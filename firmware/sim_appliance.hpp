#pragma once
// The appliance on the sim board, wired as `calbox run` wires it: the board's devices, the data
// directory, the event loop, the worker, the machine link and the cycle. The clock is the
// caller's: the real one for `calbox run` and `calbox revert`, a fake one in the tests. A
// camera of the caller's (photos from files, or the twin's wrapped) may stand in for the twin's,
// and the data directory's file calls may be a test's (a full disk).
#include <functional>

#include "board/sim/sim_board.hpp"
#include "drivers/file_storage.hpp"
#include "firmware/cycle.hpp"
#include "firmware/event_loop.hpp"
#include "firmware/gcode_host.hpp"

namespace calbox::firmware {

struct SimAppliance {
    using CameraChoice = std::function<hal::Camera&(sim::SimBoard&)>;
    sim::SimBoard board;
    drivers::FileStorage data;
    EventLoop loop;
    Worker worker{loop};
    GcodeHost host;
    hal::Camera& camera;  // the twin's, or the caller's
    Cycle cycle;

    SimAppliance(const sim::SimSettings& sim, hal::Clock& clock, GcodeHostSettings link,
                 CycleSettings settings, const Cycle::Log& log,
                 const CameraChoice& choose_camera = {},
                 drivers::FileSystemCalls& data_files = drivers::posix_file_system())
        : board(sim::make_sim_board(sim, clock, log)),
          data(sim.data_dir, data_files),
          host(*board.machine, clock, link, log),
          camera(choose_camera ? choose_camera(board) : *board.camera),
          cycle({camera, *board.lines, host, *board.display, clock, data, worker},
                board.bench->scenario().machine,
                with_setup_boards(std::move(settings), board.bench->scenario().setup), log) {
        watch_cycle(loop, cycle, host, camera, *board.lines);
    }
    // The boards the sim board's person holds are the ones the box asks for.
    static CycleSettings with_setup_boards(CycleSettings settings,
                                           const sim::ScenarioSetup& setup) {
        settings.calibration_pattern = setup.calibration_pattern;
        settings.plane_pattern = setup.plane_pattern;
        return settings;
    }
    SimAppliance(const SimAppliance&) = delete;
    SimAppliance& operator=(const SimAppliance&) = delete;
    ~SimAppliance() { loop.unwatch(host.port_fd()); }
};

}  // namespace calbox::firmware
