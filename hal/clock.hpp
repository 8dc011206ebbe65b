#pragma once
// Monotonic time and timers whose expiry is signalled on a file descriptor.
#include <chrono>
#include <cstdint>
#include <memory>

namespace calbox::hal {

class Timer {
  public:
    virtual ~Timer() = default;
    virtual int fd() const = 0;  // readable when the timer expired
    // Fires once after `after`, then every `period` unless period is zero.
    virtual void arm(std::chrono::nanoseconds after, std::chrono::nanoseconds period) = 0;
    virtual void disarm() = 0;
    // Expirations since the last call (clears the readable state).
    virtual std::uint64_t take_expirations() = 0;
};

class Clock {
  public:
    virtual ~Clock() = default;
    virtual std::chrono::nanoseconds now() const = 0;  // monotonic
    virtual std::unique_ptr<Timer> make_timer() = 0;
};

}  // namespace calbox::hal
