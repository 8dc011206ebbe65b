#pragma once
// The box under its service manager (systemd's Type=notify): ready once the loop first turns
// with every device open, a status line as the cycle goes, and the watchdog petted by a timer on
// the loop itself, so that a loop held up (a driver call that never returns, a deadlock) stops
// petting it and the manager restarts the box. "Stopping" on the way out.
#include <memory>
#include <string>

#include "firmware/cycle/cycle.hpp"
#include "firmware/loop/event_loop.hpp"
#include "hal/clock.hpp"
#include "hal/log.hpp"
#include "hal/supervisor.hpp"

namespace calbox::firmware {

// The status line the manager shows (`systemctl status calbox`): the cycle's state, what it waits
// for, the error that stopped it.
std::string service_status(const Cycle& cycle);

class ServiceWatch {
  public:
    ServiceWatch(EventLoop& loop, hal::Clock& clock, Cycle& cycle, hal::Supervisor& supervisor,
                 const hal::Log& log);
    ServiceWatch(const ServiceWatch&) = delete;
    ServiceWatch& operator=(const ServiceWatch&) = delete;
    ~ServiceWatch();  // tells the manager the box is stopping

  private:
    void tell_status();

    EventLoop& loop_;
    Cycle& cycle_;
    hal::Supervisor& supervisor_;
    std::unique_ptr<hal::Timer> ready_timer_, alive_timer_;
    CycleSubscription news_;
    std::string told_status_;
};

}  // namespace calbox::firmware
