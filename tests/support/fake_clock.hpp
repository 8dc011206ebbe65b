#pragma once
// Simulated time for the appliance's tests: timers are eventfds that fire only when the test
// advances the clock past their deadline.
#include <sys/eventfd.h>
#include <unistd.h>

#include <memory>
#include <optional>
#include <vector>

#include "hal/clock.hpp"

namespace calbox::test {

class FakeClock final : public hal::Clock {
  public:
    std::chrono::nanoseconds now() const override { return now_; }
    std::unique_ptr<hal::Timer> make_timer() override {
        auto timer = std::make_unique<FakeTimer>(*this);
        timers_.push_back(timer.get());
        return timer;
    }
    void advance(std::chrono::nanoseconds by) {
        now_ += by;
        for (auto* t : timers_) t->fire_due(now_);
    }

  private:
    class FakeTimer final : public hal::Timer {
      public:
        explicit FakeTimer(FakeClock& clock)
            : clock_(clock), fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {}
        ~FakeTimer() override {
            std::erase(clock_.timers_, this);
            ::close(fd_);
        }
        int fd() const override { return fd_; }
        void arm(std::chrono::nanoseconds after, std::chrono::nanoseconds period) override {
            deadline_ = clock_.now() + after;
            period_ = period;
        }
        void disarm() override { deadline_.reset(); }
        std::uint64_t take_expirations() override {
            std::uint64_t n = 0;
            if (::read(fd_, &n, sizeof n) != sizeof n) return 0;
            return n;
        }
        void fire_due(std::chrono::nanoseconds now) {
            while (deadline_ && *deadline_ <= now) {
                const std::uint64_t one = 1;
                if (::write(fd_, &one, sizeof one) != sizeof one) return;
                if (period_.count() > 0) {
                    *deadline_ += period_;
                } else {
                    deadline_.reset();
                }
            }
        }

      private:
        FakeClock& clock_;
        int fd_;
        std::optional<std::chrono::nanoseconds> deadline_;
        std::chrono::nanoseconds period_{0};
    };
    std::chrono::nanoseconds now_{std::chrono::seconds(1000)};
    std::vector<FakeTimer*> timers_;
};

}  // namespace calbox::test
