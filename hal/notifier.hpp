#pragma once
// An eventfd: one thread signals, the thread running the event loop sees it readable and takes
// the count. How asynchronous devices (a camera, a worker, a simulated button) report back.
#include <cstdint>

namespace calbox::hal {

class Notifier {
  public:
    Notifier();  // throws std::runtime_error when the kernel refuses an eventfd
    Notifier(const Notifier&) = delete;
    Notifier& operator=(const Notifier&) = delete;
    ~Notifier();
    int fd() const { return fd_; }
    void signal();
    std::uint64_t take();  // 0 when nothing was signalled

  private:
    int fd_ = -1;
};

}  // namespace calbox::hal
