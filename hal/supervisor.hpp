#pragma once
// The service manager the box runs under (systemd on a board): told when the box is ready, what
// it is doing, that its loop still turns, and that it is on its way out. Without one (a box run
// from a shell, the tests) every call does nothing.
#include <chrono>
#include <optional>
#include <string>

namespace calbox::hal {

class Supervisor {
  public:
    virtual ~Supervisor() = default;
    // How often the manager wants to hear that the box is alive: nothing when it does not watch.
    virtual std::optional<std::chrono::microseconds> watchdog_timeout() const = 0;
    virtual void ready() = 0;                          // the devices are open, the loop turns
    virtual void status(const std::string& line) = 0;  // one line, what the box is doing
    virtual void alive() = 0;                          // the loop turned since the last call
    virtual void stopping() = 0;                       // on the way out
};

}  // namespace calbox::hal
