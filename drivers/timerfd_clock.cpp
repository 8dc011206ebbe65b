#include "drivers/timerfd_clock.hpp"

#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

namespace calbox::drivers {
namespace {

timespec to_timespec(std::chrono::nanoseconds d) {
    const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(d);
    return timespec{static_cast<time_t>(seconds.count()), static_cast<long>((d - seconds).count())};
}

class TimerfdTimer final : public hal::Timer {
  public:
    TimerfdTimer() : fd_(::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC)) {
        if (fd_ < 0)
            throw std::runtime_error(std::string("timerfd_create: ") + std::strerror(errno));
    }
    TimerfdTimer(const TimerfdTimer&) = delete;
    TimerfdTimer& operator=(const TimerfdTimer&) = delete;
    ~TimerfdTimer() override { ::close(fd_); }
    int fd() const override { return fd_; }
    void arm(std::chrono::nanoseconds after, std::chrono::nanoseconds period) override {
        if (after <= std::chrono::nanoseconds::zero()) {
            throw std::invalid_argument("timer delay must be positive");
        }
        set(itimerspec{to_timespec(period), to_timespec(after)});
    }
    void disarm() override { set(itimerspec{}); }
    std::uint64_t take_expirations() override {
        std::uint64_t count = 0;
        const ssize_t n = ::read(fd_, &count, sizeof count);
        if (n == sizeof count) return count;
        if (n < 0 && errno == EAGAIN) return 0;
        throw std::runtime_error(std::string("timerfd read: ") + std::strerror(errno));
    }

  private:
    void set(const itimerspec& spec) {
        if (::timerfd_settime(fd_, 0, &spec, nullptr) != 0) {
            throw std::runtime_error(std::string("timerfd_settime: ") + std::strerror(errno));
        }
    }
    int fd_;
};

}  // namespace

std::chrono::nanoseconds TimerfdClock::now() const {
    timespec ts{};
    ::clock_gettime(CLOCK_MONOTONIC, &ts);
    return std::chrono::seconds(ts.tv_sec) + std::chrono::nanoseconds(ts.tv_nsec);
}

std::unique_ptr<hal::Timer> TimerfdClock::make_timer() {
    return std::make_unique<TimerfdTimer>();
}

}  // namespace calbox::drivers
