#pragma once
// The appliance (firmware/app/appliance.hpp) on the sim board's devices. The clock is the
// caller's: the real one for `calbox run` and `calbox revert`, a fake one in the tests. A
// camera of the caller's (photos from files, or the twin's wrapped) may stand in for the twin's,
// and the data directory may be the caller's (a test's full disk).
#include <functional>

#include "board/sim/sim_board.hpp"
#include "firmware/app/appliance.hpp"

namespace calbox::firmware {

struct SimAppliance {
    using CameraChoice = std::function<hal::Camera&(sim::SimBoard&)>;
    sim::SimBoard board;
    hal::Camera& camera;  // the twin's, or the caller's
    std::unique_ptr<hal::Storage> data_directory;
    Appliance appliance;
    hal::Storage& data = appliance.data;
    EventLoop& loop = appliance.loop;
    Worker& worker = appliance.worker;
    GcodeHost& host() const { return appliance.serial_host(); }
    Cycle& cycle = appliance.cycle;

    SimAppliance(const sim::SimSettings& sim, hal::Clock& clock, GcodeHostSettings link,
                 CycleSettings settings, const Cycle::Log& log,
                 const CameraChoice& choose_camera = {},
                 std::unique_ptr<hal::Storage> data = nullptr)
        : board(sim::make_sim_board(sim, clock, log)),
          camera(choose_camera ? choose_camera(board) : *board.camera),
          data_directory(data ? std::move(data) : board::data_directory(sim.data_dir)),
          appliance(ApplianceDevices::of(board.devices, &camera), *data_directory, clock, link,
                    board.machine,
                    with_setup_boards(std::move(settings), board.bench->scenario().setup), log) {}

    // The boards the sim board's person holds are the ones the box asks for.
    static CycleSettings with_setup_boards(CycleSettings settings,
                                           const sim::ScenarioSetup& setup) {
        settings.calibration_pattern = setup.calibration_pattern;
        settings.plane_pattern = setup.plane_pattern;
        return settings;
    }
    SimAppliance(const SimAppliance&) = delete;
    SimAppliance& operator=(const SimAppliance&) = delete;
};

}  // namespace calbox::firmware
