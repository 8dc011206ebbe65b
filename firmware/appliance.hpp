#pragma once
// The appliance on any board's devices, wired as `calbox run` wires it: the data directory, the
// event loop, the worker, the machine link and the cycle. The clock is the caller's: the real
// one for `calbox run` and `calbox revert`, a fake one in the tests.
#include <filesystem>

#include "board/devices.hpp"
#include "firmware/cycle.hpp"
#include "firmware/event_loop.hpp"
#include "firmware/gcode_host.hpp"
#include "hal/camera.hpp"
#include "hal/display.hpp"
#include "hal/lines.hpp"
#include "hal/serial_port.hpp"

namespace calbox::firmware {

// What the appliance needs of a board's devices (board::Devices, whichever board); each outlives
// the appliance. The camera may be another than the board's (photos from files).
struct ApplianceDevices {
    hal::Camera& camera;
    hal::Lines& lines;
    hal::Display& display;
    hal::SerialPort& machine;
    static ApplianceDevices of(board::Devices& d, hal::Camera* camera = nullptr) {
        return {camera != nullptr ? *camera : *d.camera, *d.lines, *d.display, *d.machine};
    }
};

struct Appliance {
    hal::Storage& data;
    EventLoop loop;
    Worker worker{loop};
    GcodeHost host;
    Cycle cycle;

    Appliance(ApplianceDevices devices, hal::Storage& data_dir, hal::Clock& clock,
              GcodeHostSettings link, const models::MachineFile& machine, CycleSettings settings,
              const Cycle::Log& log)
        : data(data_dir),
          host(devices.machine, clock, link, log),
          cycle({devices.camera, devices.lines, host, devices.display, clock, data, worker},
                machine, std::move(settings), log) {
        watch_cycle(loop, cycle, host, devices.camera, devices.lines);
    }
    Appliance(const Appliance&) = delete;
    Appliance& operator=(const Appliance&) = delete;
    ~Appliance() { loop.unwatch(host.port_fd()); }
};

}  // namespace calbox::firmware
