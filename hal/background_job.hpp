#pragma once
// One piece of blocking device work on a thread of its own, its end signalled on an eventfd
// for the event loop, its result taken once: how the cameras and the Modbus client keep slow
// or blocking calls off the loop.
#include <functional>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <utility>

#include "hal/notifier.hpp"

namespace calbox::hal {

template <class Result>
class BackgroundJob {
  public:
    BackgroundJob() = default;
    BackgroundJob(const BackgroundJob&) = delete;
    BackgroundJob& operator=(const BackgroundJob&) = delete;
    ~BackgroundJob() {
        if (thread_.joinable()) thread_.join();
    }

    // Throws std::logic_error while the previous job is still running.
    void start(std::function<Result()> job) {
        {
            const std::lock_guard lock(mutex_);
            if (running_) throw std::logic_error("a job is already running");
            running_ = true;
            result_.reset();
        }
        if (thread_.joinable()) thread_.join();
        thread_ = std::thread([this, job = std::move(job)] {
            Result result = job();
            {
                const std::lock_guard lock(mutex_);
                result_ = std::move(result);
                running_ = false;
            }
            done_.signal();
        });
    }
    int fd() const { return done_.fd(); }
    // The finished job's result, once; empty when none has finished since.
    std::optional<Result> take() {
        done_.take();
        const std::lock_guard lock(mutex_);
        return std::exchange(result_, std::nullopt);
    }
    bool busy() {
        const std::lock_guard lock(mutex_);
        return running_;
    }

  private:
    Notifier done_;
    std::mutex mutex_;
    std::optional<Result> result_;
    bool running_ = false;
    std::thread thread_;
};

}  // namespace calbox::hal
