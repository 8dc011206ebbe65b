#include "drivers/termios_port.hpp"

#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "drivers/fd_stream.hpp"

namespace calbox::drivers {
namespace {

speed_t speed_of(int baud) {
    switch (baud) {
        case 9600:
            return B9600;
        case 19200:
            return B19200;
        case 38400:
            return B38400;
        case 57600:
            return B57600;
        case 115200:
            return B115200;
        case 230400:
            return B230400;
        case 460800:
            return B460800;
        case 500000:
            return B500000;
        case 921600:
            return B921600;
        case 1000000:
            return B1000000;
        default:
            return static_cast<speed_t>(0);
    }
}

}  // namespace

TermiosPort::TermiosPort(const std::string& device, int baud) : device_(device) {
    const speed_t speed = speed_of(baud);
    if (speed == 0) {
        throw std::runtime_error(device + ": baud rate " + std::to_string(baud) +
                                 " is not one termios offers (9600 ... 1000000)");
    }
    fd_ = ::open(device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) throw std::runtime_error(device + ": cannot open: " + std::strerror(errno));
    termios t{};
    if (::tcgetattr(fd_, &t) != 0) {
        const std::string why = std::strerror(errno);
        ::close(fd_);
        throw std::runtime_error(device + ": not a serial device: " + why);
    }
    ::cfmakeraw(&t);
    t.c_cflag |= CLOCAL | CREAD;
    t.c_cflag &= ~static_cast<tcflag_t>(CRTSCTS);
    // VMIN 1 with O_NONBLOCK: an empty read is EAGAIN, so a read of 0 bytes means hang-up.
    t.c_cc[VMIN] = 1;
    t.c_cc[VTIME] = 0;
    ::cfsetispeed(&t, speed);
    ::cfsetospeed(&t, speed);
    if (::tcsetattr(fd_, TCSANOW, &t) != 0) {
        const std::string why = std::strerror(errno);
        ::close(fd_);
        throw std::runtime_error(device + ": cannot set raw mode: " + why);
    }
}

TermiosPort::~TermiosPort() {
    if (fd_ >= 0) ::close(fd_);
}

std::size_t TermiosPort::read_some(std::span<std::uint8_t> into) {
    return read_available(fd_, into, device_);
}

std::size_t TermiosPort::write_some(std::span<const std::uint8_t> bytes) {
    return write_available(fd_, bytes, device_);
}

}  // namespace calbox::drivers
