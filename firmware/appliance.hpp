#pragma once
// The appliance on any board's devices, wired as `calbox run` wires it: the data directory, the
// event loop, the worker, the machine link and the cycle. The clock is the caller's: the real
// one for `calbox run` and `calbox revert`, a fake one in the tests.
#include <filesystem>

#include "drivers/file_storage.hpp"
#include "firmware/cycle.hpp"
#include "firmware/event_loop.hpp"
#include "firmware/gcode_host.hpp"
#include "hal/camera.hpp"
#include "hal/display.hpp"
#include "hal/lines.hpp"
#include "hal/serial_port.hpp"

namespace calbox::firmware {

// What the appliance needs of a board; each outlives the appliance.
struct ApplianceDevices {
    hal::Camera& camera;
    hal::Lines& lines;
    hal::Display& display;
    hal::SerialPort& machine;
};

struct Appliance {
    drivers::FileStorage data;
    EventLoop loop;
    Worker worker{loop};
    GcodeHost host;
    Cycle cycle;

    Appliance(ApplianceDevices devices, const std::filesystem::path& data_dir, hal::Clock& clock,
              GcodeHostSettings link, const models::MachineFile& machine, CycleSettings settings,
              const Cycle::Log& log,
              drivers::FileSystemCalls& data_files = drivers::posix_file_system())
        : data(data_dir, data_files),
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
