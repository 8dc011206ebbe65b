#pragma once
// The servers' accepting side (drivers/http_server.cpp, drivers/tls.cpp): a listening socket, a
// thread per connection, the connections past the limit answered and drained apart, and a
// server's TLS context. Include only from the drivers' .cpp files.
#include <openssl/ssl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "drivers/asio_names.hpp"
#include "hal/http.hpp"

namespace calbox::drivers::listening {

using hal::NetworkError;

// Connections refused past the limit, after their answer: each read (what the client sent is
// drained, so that the close does not reset the connection before the answer is read) and closed
// on a thread of their own within a second, so that a client that says nothing after its refusal
// never holds up the accepting thread and the clients after it.
class Refusals {
  public:
    Refusals() : thread_([this] { run(); }) {}
    Refusals(const Refusals&) = delete;
    Refusals& operator=(const Refusals&) = delete;
    ~Refusals() {
        {
            const std::lock_guard lock(mutex_);
            stopping_ = true;
        }
        wake_.notify_all();
        thread_.join();
        for (const auto& p : pending_) {
            SSL_free(p.ssl);
            ::close(p.fd);
        }
    }
    // Takes the descriptor (answered, its sending side shut down).
    void add(int fd) { add({fd, Clock::now() + std::chrono::seconds(1), nullptr, {}, POLLIN}); }
    // Takes a non-blocking descriptor whose client speaks TLS: its handshake is led here, without
    // waiting on it, then `answer` is sent and the connection drained like the others.
    void add_tls(int fd, SSL_CTX* tls, const std::string& answer) {
        SSL* ssl = SSL_new(tls);
        if (ssl == nullptr || SSL_set_fd(ssl, fd) != 1) {
            SSL_free(ssl);
            ::close(fd);
            return;
        }
        SSL_set_accept_state(ssl);
        add({fd, Clock::now() + std::chrono::seconds(2), ssl, answer, POLLIN});
    }

  private:
    static constexpr std::size_t kMostPending = 256;
    struct Pending {
        int fd;
        Clock::time_point close_by;
        SSL* ssl;            // while its TLS handshake and answer are under way, else null
        std::string answer;  // what to send once the handshake is done
        short waits_for = POLLIN;
    };
    void add(const Pending& p) {
        bool taken = false;
        {
            const std::lock_guard lock(mutex_);
            // Past this many a flood is closed at once: its answers may be lost, not the box.
            if (pending_.size() < kMostPending) {
                pending_.push_back(p);
                taken = true;
            }
        }
        if (!taken) {
            SSL_free(p.ssl);
            ::close(p.fd);
            return;
        }
        wake_.notify_all();
    }
    // One step of a TLS refusal: false once it has failed (closed then). The answer goes as soon
    // as the handshake is done, then a close_notify and the sending side shut down.
    static bool lead_tls(Pending& p) {
        const int accepted = SSL_accept(p.ssl);
        if (accepted != 1) {
            const int error = SSL_get_error(p.ssl, accepted);
            if (error == SSL_ERROR_WANT_READ || error == SSL_ERROR_WANT_WRITE) {
                p.waits_for = error == SSL_ERROR_WANT_WRITE ? POLLOUT : POLLIN;
                return true;
            }
            return false;
        }
        // A fresh connection's send buffer takes the whole answer; one that would not is dropped.
        const bool sent = SSL_write(p.ssl, p.answer.data(), static_cast<int>(p.answer.size())) ==
                          static_cast<int>(p.answer.size());
        SSL_shutdown(p.ssl);
        SSL_free(p.ssl);
        p.ssl = nullptr;
        p.waits_for = POLLIN;
        ::shutdown(p.fd, SHUT_WR);
        return sent;
    }
    void run() {
        std::unique_lock lock(mutex_);
        for (;;) {
            wake_.wait(lock, [this] { return stopping_ || !pending_.empty(); });
            if (stopping_) return;
            std::vector<pollfd> polled;
            for (const auto& p : pending_) polled.push_back({p.fd, p.waits_for, 0});
            lock.unlock();
            ::poll(polled.data(), polled.size(), 50);
            lock.lock();
            const auto now = Clock::now();
            std::array<char, 4096> sink{};
            for (auto it = pending_.begin(); it != pending_.end();) {
                const auto seen = std::find_if(polled.begin(), polled.end(),
                                               [&](const pollfd& p) { return p.fd == it->fd; });
                bool done = now >= it->close_by;
                const bool ready = seen != polled.end() &&
                                   (seen->revents & (it->waits_for | POLLHUP | POLLERR)) != 0;
                if (!done && ready && it->ssl != nullptr)
                    done = !lead_tls(*it);
                else if (!done && ready)
                    done = ::recv(it->fd, sink.data(), sink.size(), MSG_DONTWAIT) <= 0;
                if (done) {
                    SSL_free(it->ssl);
                    ::close(it->fd);
                    it = pending_.erase(it);
                } else {
                    ++it;
                }
            }
        }
    }
    std::mutex mutex_;
    std::condition_variable wake_;
    std::vector<Pending> pending_;  // under mutex_
    bool stopping_ = false;         // under mutex_
    std::thread thread_;            // last: it uses the rest
};

// Listens on a port of `address` (0: a free one) and serves each connection it accepts on a
// thread of its own, keeping the connections' descriptors so that they can be shut down (a host
// restarting, the server going).
class Listener {
  public:
    Listener(const std::string& address, int port) {
        boost::system::error_code ec;
        const tcp::endpoint at(net::ip::make_address(address, ec),
                               static_cast<unsigned short>(port));
        if (ec) throw NetworkError(address + ": " + ec.message());
        acceptor_.open(at.protocol(), ec);
        if (!ec) acceptor_.set_option(net::socket_base::reuse_address(true), ec);
        if (!ec) acceptor_.bind(at, ec);
        if (!ec) acceptor_.listen(net::socket_base::max_listen_connections, ec);
        if (ec)
            throw NetworkError(address + ":" + std::to_string(port) +
                               ": cannot listen: " + ec.message());
        port_ = acceptor_.local_endpoint().port();
    }
    Listener(const Listener&) = delete;
    Listener& operator=(const Listener&) = delete;
    ~Listener() { stop(); }

    int port() const { return port_; }

    // `serve` runs on each connection's thread; the connection's descriptor is tracked. Past
    // `max_connections` (0: no limit) a connection is sent `refusal` (a whole HTTP answer's
    // bytes) instead, without waiting on the client (over TLS once refusals_ has led its
    // handshake), then drained and closed by refusals_.
    void start(std::function<void(tcp::socket)> serve, int max_connections = 0,
               std::string refusal = {}, SSL_CTX* tls = nullptr) {
        accepting_ = std::thread(
            [this, serve = std::move(serve), max_connections, refusal = std::move(refusal), tls] {
                for (;;) {
                    boost::system::error_code e;
                    tcp::socket socket(ioc_);
                    acceptor_.accept(socket, e);
                    const std::lock_guard lock(mutex_);
                    if (stopping_) return;
                    if (e) continue;
                    reap();
                    if (max_connections > 0 && serving() >= max_connections) {
                        socket.non_blocking(true, e);
                        if (tls != nullptr) {
                            refusals_.add_tls(socket.release(e), tls, refusal);
                            continue;
                        }
                        // A fresh socket's send buffer takes the whole answer; one that would
                        // not is dropped rather than hold up the accepting thread.
                        (void)::send(socket.native_handle(), refusal.data(), refusal.size(),
                                     MSG_NOSIGNAL | MSG_DONTWAIT);
                        socket.shutdown(tcp::socket::shutdown_send, e);
                        refusals_.add(socket.release(e));
                        continue;
                    }
                    const int fd = socket.native_handle();
                    open_fds_.insert(fd);
                    auto done = std::make_shared<std::atomic<bool>>(false);
                    connections_.push_back(
                        {std::thread([serve, done, socket = std::move(socket)]() mutable {
                             serve(std::move(socket));
                             *done = true;
                         }),
                         done, fd});
                }
            });
    }
    // Another descriptor a connection opened (false, and not tracked, once stopping).
    bool track(int fd) {
        const std::lock_guard lock(mutex_);
        if (stopping_) return false;
        open_fds_.insert(fd);
        return true;
    }
    // A connection's descriptor, before it closes.
    void forget(int fd) {
        const std::lock_guard lock(mutex_);
        open_fds_.erase(fd);
    }
    // Shuts a connection down and frees its place at once: its client sees the close before its
    // thread has woken to end, and a request that follows must not find the server still full.
    void let_go(int fd) {
        const std::lock_guard lock(mutex_);
        ::shutdown(fd, SHUT_RDWR);
        // The newest with this descriptor: an older one may have closed it and not yet ended.
        for (auto it = connections_.rbegin(); it != connections_.rend(); ++it) {
            if (it->fd == fd) {
                it->let_go = true;
                break;
            }
        }
    }
    void drop_connections() {
        const std::lock_guard lock(mutex_);
        for (const int fd : open_fds_) ::shutdown(fd, SHUT_RDWR);
    }
    // No more connections; those open shut down and their threads joined.
    void stop() {
        {
            const std::lock_guard lock(mutex_);
            if (stopping_) return;
            stopping_ = true;
            // A blocked accept() returns once its socket is shut down.
            ::shutdown(acceptor_.native_handle(), SHUT_RDWR);
        }
        if (accepting_.joinable()) accepting_.join();
        drop_connections();
        for (auto& c : connections_) c.thread.join();
        connections_.clear();
    }

  private:
    struct Connection {
        std::thread thread;
        std::shared_ptr<std::atomic<bool>> done;
        int fd = -1;
        bool let_go = false;  // shut down by the server: no longer holds a place
    };
    // The connections that hold a place. Under mutex_.
    int serving() const {
        int n = 0;
        for (const auto& c : connections_) n += (!*c.done && !c.let_go) ? 1 : 0;
        return n;
    }
    // Joins the connections that ended: a box serving a page for months opens many. Under mutex_.
    void reap() {
        for (auto it = connections_.begin(); it != connections_.end();) {
            if (*it->done) {
                it->thread.join();
                it = connections_.erase(it);
            } else {
                ++it;
            }
        }
    }

    net::io_context ioc_;
    tcp::acceptor acceptor_{ioc_};
    int port_ = 0;
    std::mutex mutex_;
    std::set<int> open_fds_;
    std::list<Connection> connections_;
    Refusals refusals_;
    std::thread accepting_;
    bool stopping_ = false;
};

// A server's TLS: TLS 1.2 and later, a certificate chain and its key in PEM text, the key checked
// against the certificate. `chain_from` and `key_from` name them in its errors.
std::unique_ptr<ssl::context> server_tls_context(const std::string& chain_pem,
                                                 const std::string& chain_from,
                                                 const std::string& key_pem,
                                                 const std::string& key_from);
// A PEM file's text; throws NetworkError naming it.
std::string pem_file_text(const std::string& path);

}  // namespace calbox::drivers::listening
