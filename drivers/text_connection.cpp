#include "drivers/text_connection.hpp"

#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace calbox::drivers {
namespace {

using hal::NetworkError;
using Clock = std::chrono::steady_clock;

int milliseconds_left(Clock::time_point until) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    return left.count() < 0 ? 0 : static_cast<int>(left.count());
}

class TcpTextConnection final : public hal::TextConnection {
  public:
    TcpTextConnection(int fd, std::string peer) : fd_(fd), peer_(std::move(peer)) {}
    TcpTextConnection(const TcpTextConnection&) = delete;
    TcpTextConnection& operator=(const TcpTextConnection&) = delete;
    ~TcpTextConnection() override { ::close(fd_); }

    void write_line(const std::string& line) override {
        const std::string bytes = line + "\r\n";
        std::size_t sent = 0;
        const auto until = Clock::now() + std::chrono::seconds(10);
        while (sent < bytes.size()) {
            const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
            if (n > 0) {
                sent += static_cast<std::size_t>(n);
                continue;
            }
            if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
                throw NetworkError(peer_ + ": " + std::strerror(errno));
            if (!wait_for(POLLOUT, until)) throw NetworkError(peer_ + ": the peer takes nothing");
        }
    }

    std::optional<std::string> read_line(std::chrono::milliseconds timeout) override {
        const auto until = Clock::now() + timeout;
        for (;;) {
            const auto end = buffer_.find('\n');
            if (end != std::string::npos) {
                std::string line = buffer_.substr(0, end);
                buffer_.erase(0, end + 1);
                while (!line.empty() && (line.back() == '\r' || line.back() == '\n'))
                    line.pop_back();
                // linuxcncrsh ends its lines "\n\r" in places: the "\r" starts the next line.
                while (!line.empty() && line.front() == '\r') line.erase(0, 1);
                return line;
            }
            if (!wait_for(POLLIN, until)) return std::nullopt;
            char chunk[1024];
            const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
            if (n == 0) throw NetworkError(peer_ + ": the peer closed the connection");
            if (n < 0) {
                if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) continue;
                throw NetworkError(peer_ + ": " + std::strerror(errno));
            }
            buffer_.append(chunk, static_cast<std::size_t>(n));
        }
    }

  private:
    bool wait_for(short events, Clock::time_point until) const {
        pollfd p{fd_, events, 0};
        for (;;) {
            const int r = ::poll(&p, 1, milliseconds_left(until));
            if (r > 0) return true;
            if (r == 0) return false;
            if (errno != EINTR) throw NetworkError(peer_ + ": " + std::strerror(errno));
        }
    }

    int fd_;
    std::string peer_;
    std::string buffer_;
};

// One address tried within the time left: the connected socket, or -1 with `why` set.
int connect_one(const addrinfo& a, Clock::time_point until, std::string& why) {
    const int fd =
        ::socket(a.ai_family, a.ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a.ai_protocol);
    if (fd < 0) {
        why = std::strerror(errno);
        return -1;
    }
    if (::connect(fd, a.ai_addr, a.ai_addrlen) == 0) return fd;
    if (errno == EINPROGRESS) {
        pollfd p{fd, POLLOUT, 0};
        int r;
        do r = ::poll(&p, 1, milliseconds_left(until));
        while (r < 0 && errno == EINTR);
        int error = 0;
        socklen_t size = sizeof error;
        if (r > 0 && ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &size) == 0 && error == 0)
            return fd;
        why = r == 0 ? std::string("no answer in time") : std::string(std::strerror(error));
    } else {
        why = std::strerror(errno);
    }
    ::close(fd);
    return -1;
}

}  // namespace

std::unique_ptr<hal::TextConnection> connect_text(const std::string& host, int port,
                                                  std::chrono::milliseconds timeout) {
    const std::string peer = host + ":" + std::to_string(port);
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* found = nullptr;
    const std::string service = std::to_string(port);
    if (const int e = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found); e != 0)
        throw NetworkError(peer + ": " + ::gai_strerror(e));
    const auto until = Clock::now() + timeout;
    std::string why = "no address";
    int fd = -1;
    for (const addrinfo* a = found; a != nullptr && fd < 0; a = a->ai_next)
        fd = connect_one(*a, until, why);
    ::freeaddrinfo(found);
    if (fd < 0) throw NetworkError(peer + ": " + why);
    return std::make_unique<TcpTextConnection>(fd, peer);
}

}  // namespace calbox::drivers
