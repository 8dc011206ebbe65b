#include "firmware/loop/event_loop.hpp"

#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace calbox::firmware {
namespace {

std::runtime_error os_error(const std::string& what) {
    return std::runtime_error(what + ": " + std::strerror(errno));
}

}  // namespace

EventLoop::EventLoop() : epoll_fd_(::epoll_create1(EPOLL_CLOEXEC)) {
    if (epoll_fd_ < 0) throw os_error("epoll_create1");
}

EventLoop::~EventLoop() {
    ::close(epoll_fd_);
}

void EventLoop::watch(int fd, std::function<void()> handler) {
    if (handlers_.count(fd) != 0)
        throw std::logic_error("fd " + std::to_string(fd) + " watched twice");
    epoll_event e{};
    e.events = EPOLLIN;
    e.data.fd = fd;
    if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &e) != 0) throw os_error("epoll_ctl add");
    handlers_[fd] = std::make_shared<std::function<void()>>(std::move(handler));
}

void EventLoop::unwatch(int fd) {
    if (handlers_.erase(fd) == 0) return;
    ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, fd, nullptr);
}

int EventLoop::run_once(std::chrono::milliseconds timeout) {
    std::vector<epoll_event> events(16);
    const int n = ::epoll_wait(epoll_fd_, events.data(), static_cast<int>(events.size()),
                               static_cast<int>(timeout.count()));
    if (n < 0) {
        if (errno == EINTR) return 0;
        throw os_error("epoll_wait");
    }
    int ran = 0;
    for (int i = 0; i < n; ++i) {
        // A handler may unwatch another fd of the same batch: look it up each time, and keep
        // it alive while it runs even if it unwatches itself.
        const auto it = handlers_.find(events[static_cast<std::size_t>(i)].data.fd);
        if (it == handlers_.end()) continue;
        const auto handler = it->second;
        (*handler)();
        ++ran;
    }
    return ran;
}

void EventLoop::run() {
    stopped_ = false;
    while (!stopped_) run_once(std::chrono::milliseconds(1000));
}

LoopInbox::LoopInbox(EventLoop& loop) : loop_(loop) {
    loop_.watch(wakeup_.fd(), [this] { run_posted(); });
}

LoopInbox::~LoopInbox() {
    loop_.unwatch(wakeup_.fd());
}

void LoopInbox::post(std::function<void()> job) {
    {
        const std::lock_guard lock(mutex_);
        jobs_.push_back(std::move(job));
    }
    wakeup_.signal();
}

void LoopInbox::run_posted() {
    wakeup_.take();
    std::deque<std::function<void()>> jobs;
    {
        const std::lock_guard lock(mutex_);
        jobs.swap(jobs_);
    }
    for (auto& job : jobs) job();
}

Worker::Worker(EventLoop& loop) : loop_(loop) {
    loop_.watch(job_.fd(), [this] { finished(); });
}

Worker::~Worker() {
    loop_.unwatch(job_.fd());
}

void Worker::start(std::function<void()> work, std::function<void(std::exception_ptr)> done) {
    if (busy_) throw std::logic_error("the worker is busy");
    busy_ = true;
    done_ = std::move(done);
    job_.start([work = std::move(work)]() -> std::exception_ptr {
        try {
            work();
            return nullptr;
        } catch (...) {
            return std::current_exception();
        }
    });
}

void Worker::finished() {
    auto error = job_.take();
    if (!error) return;
    busy_ = false;
    auto done = std::move(done_);
    done_ = nullptr;
    if (done) done(*error);
}

SignalWatch::SignalWatch() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGINT);
    if (::pthread_sigmask(SIG_BLOCK, &set, nullptr) != 0) throw os_error("pthread_sigmask");
    fd_ = ::signalfd(-1, &set, SFD_NONBLOCK | SFD_CLOEXEC);
    if (fd_ < 0) throw os_error("signalfd");
}

SignalWatch::~SignalWatch() {
    ::close(fd_);
}

int SignalWatch::take() {
    signalfd_siginfo info{};
    if (::read(fd_, &info, sizeof info) != sizeof info) return 0;
    return static_cast<int>(info.ssi_signo);
}

}  // namespace calbox::firmware
