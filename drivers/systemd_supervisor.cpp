#include "drivers/systemd_supervisor.hpp"

#include <systemd/sd-daemon.h>

#include <cstdint>
#include <string>

namespace calbox::drivers {

SystemdSupervisor::SystemdSupervisor() {
    std::uint64_t usec = 0;
    // 0 leaves WATCHDOG_USEC in the environment: a process the box starts never inherits it (the
    // box starts none), and a restart of the box reads it again.
    if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0)
        watchdog_timeout_ = std::chrono::microseconds(static_cast<std::int64_t>(usec));
}

// sd_notify's failures (no socket, the manager gone) are not the box's to act on: the unit
// restarts a box whose notifications stop, and a box run by hand has no one to tell.
void SystemdSupervisor::ready() {
    sd_notify(0, "READY=1");
}

void SystemdSupervisor::status(const std::string& line) {
    std::string message = "STATUS=" + line;
    // One line: the protocol's fields end at a newline.
    for (char& c : message)
        if (c == '\n') c = ' ';
    sd_notify(0, message.c_str());
}

void SystemdSupervisor::alive() {
    sd_notify(0, "WATCHDOG=1");
}

void SystemdSupervisor::stopping() {
    sd_notify(0, "STOPPING=1");
}

}  // namespace calbox::drivers
