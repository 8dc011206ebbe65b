#pragma once
// A non-blocking byte stream to a machine (G-code over USB serial) or a console.
#include <cstddef>
#include <cstdint>
#include <span>

namespace calbox::hal {

class SerialPort {
  public:
    virtual ~SerialPort() = default;
    virtual int fd() const = 0;  // readable when bytes arrived
    // Reads what is there without waiting; returns the count (0 when nothing is pending).
    // Throws std::runtime_error when the link is gone.
    virtual std::size_t read_some(std::span<std::uint8_t> into) = 0;
    // Writes what fits without waiting; returns the count written.
    virtual std::size_t write_some(std::span<const std::uint8_t> bytes) = 0;
};

}  // namespace calbox::hal
