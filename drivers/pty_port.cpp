#include "drivers/pty_port.hpp"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include "drivers/fd_stream.hpp"

namespace calbox::drivers {
namespace {

std::runtime_error pty_error(const char* what) {
    return std::runtime_error(std::string("console pty: ") + what + ": " + std::strerror(errno));
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
    return read_available(master_, into, "console pty");
}

std::size_t PtyPort::write_some(std::span<const std::uint8_t> bytes) {
    return write_available(master_, bytes, "console pty");
}

std::size_t StdioPort::read_some(std::span<std::uint8_t> into) {
    return read_available(0, into, "standard input");
}

std::size_t StdioPort::write_some(std::span<const std::uint8_t> bytes) {
    return write_available(1, bytes, "standard output");
}

}  // namespace calbox::drivers
