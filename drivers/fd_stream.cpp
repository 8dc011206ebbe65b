#include "drivers/fd_stream.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace calbox::drivers {

std::size_t read_available(int fd, std::span<std::uint8_t> into, const std::string& name) {
    while (true) {
        const ssize_t n = ::read(fd, into.data(), into.size());
        if (n > 0) return static_cast<std::size_t>(n);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return 0;
        // A tty that reads end-of-file or EIO has lost its far end (hang-up, USB gone).
        throw std::runtime_error(name + ": link gone (" +
                                 (n == 0 ? std::string("hang-up") : std::strerror(errno)) + ")");
    }
}

std::size_t write_available(int fd, std::span<const std::uint8_t> bytes, const std::string& name) {
    while (true) {
        const ssize_t n = ::write(fd, bytes.data(), bytes.size());
        if (n >= 0) return static_cast<std::size_t>(n);
        if (errno == EINTR) continue;
        if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
        throw std::runtime_error(name + ": link gone (" + std::strerror(errno) + ")");
    }
}

}  // namespace calbox::drivers
