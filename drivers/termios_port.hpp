#pragma once
#include <string>

#include "hal/serial_port.hpp"

namespace calbox::drivers {

// A serial device (a real tty or a pseudo-terminal) in raw mode, non-blocking.
class TermiosPort final : public hal::SerialPort {
  public:
    // Throws std::runtime_error naming the device: missing, permission denied, not a tty, or a
    // baud rate termios does not have.
    TermiosPort(const std::string& device, int baud);
    TermiosPort(const TermiosPort&) = delete;
    TermiosPort& operator=(const TermiosPort&) = delete;
    ~TermiosPort() override;
    int fd() const override { return fd_; }
    // Throws std::runtime_error("<device>: link gone ...") when the device vanished (USB
    // unplugged, the far end of a pty closed).
    std::size_t read_some(std::span<std::uint8_t> into) override;
    std::size_t write_some(std::span<const std::uint8_t> bytes) override;
    const std::string& device() const { return device_; }

  private:
    std::string device_;
    int fd_ = -1;
};

}  // namespace calbox::drivers
