#pragma once
#include "hal/clock.hpp"

namespace calbox::drivers {

// CLOCK_MONOTONIC and timerfd timers.
class TimerfdClock final : public hal::Clock {
  public:
    std::chrono::nanoseconds now() const override;
    std::unique_ptr<hal::Timer> make_timer() override;
};

}  // namespace calbox::drivers
