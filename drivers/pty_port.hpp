#pragma once
// The sim board's console device: a pseudo-terminal whose far end (slave_path()) a terminal
// program or a test opens as it would open a UART. The box keeps the far end open itself, so
// a client that disconnects and comes back finds the console as it left it (a pty whose last
// far end closes hangs up for good).
#include <string>

#include "hal/serial_port.hpp"

namespace calbox::drivers {

class PtyPort final : public hal::SerialPort {
  public:
    PtyPort();  // throws std::runtime_error with the system's reason
    PtyPort(const PtyPort&) = delete;
    PtyPort& operator=(const PtyPort&) = delete;
    ~PtyPort() override;
    int fd() const override { return master_; }
    std::size_t read_some(std::span<std::uint8_t> into) override;
    std::size_t write_some(std::span<const std::uint8_t> bytes) override;
    const std::string& slave_path() const { return slave_path_; }

  private:
    int master_ = -1;
    int kept_slave_ = -1;
    std::string slave_path_;
};

// Standard input and output as a console (the sim board at a terminal).
class StdioPort final : public hal::SerialPort {
  public:
    int fd() const override { return 0; }
    std::size_t read_some(std::span<std::uint8_t> into) override;  // end of input: throws
    std::size_t write_some(std::span<const std::uint8_t> bytes) override;
};

}  // namespace calbox::drivers
