#include "drivers/pty_port.hpp"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace calbox::drivers {
namespace {

std::runtime_error pty_error(const char* what) {
    return std::runtime_error(std::string("console pty: ") + what + ": " + std::strerror(errno));
}

std::size_t read_ready(int fd, std::span<std::uint8_t> into, const char* gone) {
    while (true) {
        const ssize_t n = ::read(fd, into.data(), into.size());
        if (n > 0) return static_cast<std::size_t>(n);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return 0;
        throw std::runtime_error(std::string(gone) +
                                 (n == 0 ? std::string(" (end of input)") : std::strerror(errno)));
    }
}

std::size_t write_ready(int fd, std::span<const std::uint8_t> bytes, const char* gone) {
    while (true) {
        const ssize_t n = ::write(fd, bytes.data(), bytes.size());
        if (n >= 0) return static_cast<std::size_t>(n);
        if (errno == EINTR) continue;
        if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
        throw std::runtime_error(std::string(gone) + std::strerror(errno));
    }
}

}  // namespace

PtyPort::PtyPort() {
    master_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (master_ < 0) throw pty_error("cannot open a pseudo-terminal");
    try {
        if (::grantpt(master_) != 0 || ::unlockpt(master_) != 0) throw pty_error("cannot unlock");
        char name[128];
        if (::ptsname_r(master_, name, sizeof name) != 0) throw pty_error("no name");
        slave_path_ = name;
        kept_slave_ = ::open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
        if (kept_slave_ < 0) throw pty_error("cannot open its far end");
        // Raw on the far end: lines arrive as typed, nothing is echoed or translated; a client
        // that wants echo turns it on in its own terminal program.
        termios t{};
        if (::tcgetattr(kept_slave_, &t) != 0) throw pty_error("tcgetattr");
        ::cfmakeraw(&t);
        if (::tcsetattr(kept_slave_, TCSANOW, &t) != 0) throw pty_error("tcsetattr");
        const int flags = ::fcntl(master_, F_GETFL);
        if (flags < 0 || ::fcntl(master_, F_SETFL, flags | O_NONBLOCK) != 0)
            throw pty_error("cannot make it non-blocking");
    } catch (...) {
        if (kept_slave_ >= 0) ::close(kept_slave_);
        ::close(master_);
        throw;
    }
}

PtyPort::~PtyPort() {
    ::close(kept_slave_);
    ::close(master_);
}

std::size_t PtyPort::read_some(std::span<std::uint8_t> into) {
    return read_ready(master_, into, "console pty: gone: ");
}

std::size_t PtyPort::write_some(std::span<const std::uint8_t> bytes) {
    return write_ready(master_, bytes, "console pty: gone: ");
}

std::size_t StdioPort::read_some(std::span<std::uint8_t> into) {
    return read_ready(0, into, "standard input: closed");
}

std::size_t StdioPort::write_some(std::span<const std::uint8_t> bytes) {
    return write_ready(1, bytes, "standard output: ");
}

}  // namespace calbox::drivers
