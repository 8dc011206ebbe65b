#pragma once
// Non-blocking reads and writes on a byte stream's descriptor (a tty, a pty, standard input), as
// the SerialPort drivers all do them: what is there or what fits, 0 when nothing is, and a far end
// that is gone (end of file, EIO) thrown as std::runtime_error("<name>: link gone (<why>)").
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace calbox::drivers {

std::size_t read_available(int fd, std::span<std::uint8_t> into, const std::string& name);
std::size_t write_available(int fd, std::span<const std::uint8_t> bytes, const std::string& name);

}  // namespace calbox::drivers
