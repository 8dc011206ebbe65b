#pragma once
// systemd as the box's supervisor (sd_notify): READY=1, STATUS=, WATCHDOG=1 and STOPPING=1 on the
// socket the unit's Type=notify gives (NOTIFY_SOCKET); with no socket every call does nothing.
#include "hal/supervisor.hpp"

namespace calbox::drivers {

class SystemdSupervisor final : public hal::Supervisor {
  public:
    SystemdSupervisor();  // reads the watchdog's timeout systemd set (WATCHDOG_USEC) once
    std::optional<std::chrono::microseconds> watchdog_timeout() const override {
        return watchdog_timeout_;
    }
    void ready() override;
    void status(const std::string& line) override;
    void alive() override;
    void stopping() override;

  private:
    std::optional<std::chrono::microseconds> watchdog_timeout_;
};

}  // namespace calbox::drivers
