#pragma once
// The appliance on any board's devices, wired as `calbox run` wires it: the data directory, the
// event loop, the worker, the machine link and the cycle. The clock is the caller's: the real
// one for `calbox run` and `calbox revert`, a fake one in the tests.
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "board/devices.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/links/gcode_host.hpp"
#include "firmware/links/make_link.hpp"
#include "firmware/loop/event_loop.hpp"
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
    hal::SerialPort* machine;  // the machine's serial port; none for a machine behind a host
    hal::Network* network;     // a host's link (HTTP, linuxcncrsh); none without a network
    static ApplianceDevices of(board::Devices& d, hal::Camera* camera = nullptr) {
        return {camera != nullptr ? *camera : *d.camera, *d.lines, *d.display, d.machine.get(),
                d.network.get()};
    }
};

struct Appliance {
    hal::Storage& data;
    EventLoop loop;
    Worker worker{loop};
    std::unique_ptr<MachineLink> link;
    Cycle cycle;

    Appliance(ApplianceDevices devices, hal::Storage& data_dir, hal::Clock& clock,
              GcodeHostSettings serial, const models::MachineFile& machine, CycleSettings settings,
              const Cycle::Log& log)
        : data(data_dir),
          link(make_machine_link(machine, devices.machine, devices.network, clock, serial, log)),
          cycle({devices.camera, devices.lines, *link, devices.display, clock, data, worker},
                machine, std::move(settings), log) {
        watch_cycle(loop, cycle, *link, devices.camera, devices.lines);
    }
    Appliance(const Appliance&) = delete;
    Appliance& operator=(const Appliance&) = delete;
    ~Appliance() { link->detach(loop); }
    // The serial link's host (its transcript), for tests; throws std::logic_error for a host's.
    GcodeHost& serial_host() const {
        auto* host = dynamic_cast<GcodeHost*>(link.get());
        if (host == nullptr) throw std::logic_error("the machine link is not a serial port");
        return *host;
    }
};

}  // namespace calbox::firmware
