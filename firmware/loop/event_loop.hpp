#pragma once
// One thread, one epoll set: every source of work (button line, timers, signals, the machine
// link, the console, the camera's and the worker's completions) is a readable file descriptor
// with a handler. Handlers run on the loop's thread, one at a time, and never block.
#include <chrono>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "hal/background_job.hpp"
#include "hal/notifier.hpp"

namespace calbox::firmware {

class EventLoop {
  public:
    EventLoop();
    EventLoop(const EventLoop&) = delete;
    EventLoop& operator=(const EventLoop&) = delete;
    ~EventLoop();

    // Calls `handler` whenever `fd` is readable (or hung up). Throws std::logic_error for an fd
    // already watched.
    void watch(int fd, std::function<void()> handler);
    void unwatch(int fd);
    // Handles what is ready, waiting up to `timeout` for something; returns how many handlers ran.
    int run_once(std::chrono::milliseconds timeout);
    // Runs until stop(); a handler that throws ends the run with that exception.
    void run();
    void stop() { stopped_ = true; }
    bool stopped() const { return stopped_; }

  private:
    int epoll_fd_ = -1;
    std::map<int, std::shared_ptr<std::function<void()>>> handlers_;
    bool stopped_ = false;
};

// Other threads' requests to the loop (the web server's connections, the MQTT client's): each job
// runs on the loop's thread, in the order posted, so that the cycle, the console and the
// configuration are only ever touched there.
class LoopInbox {
  public:
    explicit LoopInbox(EventLoop& loop);
    LoopInbox(const LoopInbox&) = delete;
    LoopInbox& operator=(const LoopInbox&) = delete;
    ~LoopInbox();  // jobs still queued are dropped; anyone waiting on call() gets nothing
    void post(std::function<void()> job);  // from any thread
    // Runs `job` on the loop's thread and waits up to `within` for its result: nothing when the
    // loop did not run it in time (stopped, or the inbox going). From any thread but the loop's.
    template <class T>
    std::optional<T> call(std::function<T()> job, std::chrono::milliseconds within) {
        auto promise = std::make_shared<std::promise<T>>();
        auto result = promise->get_future();
        post([promise, job = std::move(job)] {
            try {
                promise->set_value(job());
            } catch (...) {
                promise->set_exception(std::current_exception());
            }
        });
        if (result.wait_for(within) != std::future_status::ready) return std::nullopt;
        return result.get();  // the job's exception, rethrown here
    }

  private:
    void run_posted();
    EventLoop& loop_;
    hal::Notifier wakeup_;
    std::mutex mutex_;
    std::deque<std::function<void()>> jobs_;  // under the mutex
};

// Runs slow work (measure, solve, calibrate) off the loop: `work` on the worker's thread, then
// `done` on the loop's thread when the loop sees the completion. One job at a time.
class Worker {
  public:
    explicit Worker(EventLoop& loop);
    Worker(const Worker&) = delete;
    Worker& operator=(const Worker&) = delete;
    ~Worker();  // waits for a running job
    // Throws std::logic_error while a job runs. `work`'s exception is handed to `done`.
    void start(std::function<void()> work, std::function<void(std::exception_ptr)> done);
    bool busy() const { return busy_; }

  private:
    void finished();
    EventLoop& loop_;
    std::function<void(std::exception_ptr)> done_;
    bool busy_ = false;
    hal::BackgroundJob<std::exception_ptr> job_;  // last: joined before the rest goes
};

// SIGTERM and SIGINT as a file descriptor: blocked for ordinary delivery, read by the loop.
class SignalWatch {
  public:
    SignalWatch();
    SignalWatch(const SignalWatch&) = delete;
    SignalWatch& operator=(const SignalWatch&) = delete;
    ~SignalWatch();
    int fd() const { return fd_; }
    int take();  // the signal number, 0 when none

  private:
    int fd_ = -1;
};

}  // namespace calbox::firmware
