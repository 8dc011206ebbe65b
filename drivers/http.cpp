#include "drivers/http.hpp"

#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509v3.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/stream_traits.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <cctype>
#include <condition_variable>
#include <ctime>
#include <deque>
#include <filesystem>
#include <fstream>
#include <list>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <type_traits>
#include <vector>

namespace calbox::drivers {
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
namespace ssl = net::ssl;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

namespace {

// A file sent to a host may be a whole print; a reply may be a whole printer.cfg.
constexpr std::uint64_t kBodyLimitBytes = 64ull << 20;

// Runs the io_context one handler at a time until `done` or the deadline; false on the deadline.
bool run_until(net::io_context& ioc, const bool& done, Clock::time_point deadline) {
    while (!done) {
        const auto now = Clock::now();
        if (now >= deadline) return false;
        ioc.restart();
        ioc.run_one_for(deadline - now);
    }
    return true;
}

// A client's step (connecting, the TLS and websocket handshakes, sending, the reply) finishes
// within `timeout` or is ended: its socket closed, its handlers run out (they refer to the
// caller's locals), false returned. Deadlines of our own on plain sockets rather than Beast's
// timed stream: every operation on that stream is a template instance of its own, and they
// made this file the build's longest.
bool finish_within(net::io_context& ioc, const bool& done, std::chrono::milliseconds timeout,
                   tcp::socket& socket) {
    if (run_until(ioc, done, Clock::now() + timeout)) return true;
    boost::system::error_code ignored;
    socket.close(ignored);
    ioc.restart();
    ioc.run();
    return false;
}

std::string within_phrase(std::chrono::milliseconds timeout) {
    return "within " + std::to_string(timeout.count()) + " ms";
}

std::string describe(const Url& url) {
    return url.origin();
}

}  // namespace

namespace {

// The TLS context of a client of `url`: the peer's certificate checked against the system's
// certificate authorities, or against the url's ca_file alone (a host with a certificate of its
// own making).
std::unique_ptr<ssl::context> client_context(const Url& url) {
    auto ctx = std::make_unique<ssl::context>(ssl::context::tls_client);
    boost::system::error_code ec;
    if (url.ca_file.empty())
        ctx->set_default_verify_paths(ec);
    else
        ctx->load_verify_file(url.ca_file, ec);
    if (ec)
        throw NetworkError(url.origin() + ": the certificate authorities" +
                           (url.ca_file.empty() ? "" : " in " + url.ca_file) + ": " + ec.message());
    ctx->set_verify_mode(ssl::verify_peer);
    return ctx;
}

// TLS over a connected socket: the host's name sent (SNI) and checked against its certificate.
void tls_handshake(net::io_context& ioc, ssl::stream<tcp::socket>& stream, const Url& url,
                   std::chrono::milliseconds timeout, const std::string& where) {
    if (SSL_set_tlsext_host_name(stream.native_handle(), url.host.c_str()) != 1)
        throw NetworkError(where + ": the host name cannot be sent for TLS");
    stream.set_verify_callback(ssl::host_name_verification(url.host));
    boost::system::error_code ec;
    bool done = false;
    stream.async_handshake(ssl::stream_base::client, [&](boost::system::error_code e) {
        ec = e;
        done = true;
    });
    if (!finish_within(ioc, done, timeout, stream.next_layer()))
        throw NetworkError(where + ": TLS: no handshake " + within_phrase(timeout));
    if (ec) throw NetworkError(where + ": TLS: " + ec.message());
}

void connect(net::io_context& ioc, tcp::socket& socket, const Url& server,
             std::chrono::milliseconds timeout, const std::string& where) {
    boost::system::error_code ec;
    tcp::resolver resolver(ioc);
    const auto endpoints = resolver.resolve(server.host, server.port, ec);
    if (ec) throw NetworkError(where + ": " + ec.message());
    bool done = false;
    net::async_connect(socket, endpoints, [&](boost::system::error_code e, const tcp::endpoint&) {
        ec = e;
        done = true;
    });
    if (!finish_within(ioc, done, timeout, socket))
        throw NetworkError(where + ": no connection " + within_phrase(timeout));
    if (ec) throw NetworkError(where + ": " + ec.message());
}

// One request and its reply on a connected stream (the socket itself, or TLS over it).
template <class Stream>
HttpResponse exchange(net::io_context& ioc, Stream& stream, tcp::socket& socket, const Url& server,
                      const HttpRequest& request, std::chrono::milliseconds timeout,
                      const std::string& where) {
    boost::system::error_code ec;
    http::request<http::string_body> req{http::string_to_verb(request.method), request.target, 11};
    if (req.method() == http::verb::unknown)
        throw std::invalid_argument("HTTP method '" + request.method + "'");
    req.set(http::field::host, server.host);
    req.set(http::field::user_agent, "calbox");
    for (const auto& [name, value] : request.headers) req.set(name, value);
    if (!request.content_type.empty()) req.set(http::field::content_type, request.content_type);
    req.body() = request.body;
    req.prepare_payload();
    // The path alone in what is said: a query may carry a password (rr_connect's).
    const std::string path = request.target.substr(0, request.target.find('?'));
    bool sent = false;
    http::async_write(stream, req, [&](boost::system::error_code e, std::size_t) {
        ec = e;
        sent = true;
    });
    if (!finish_within(ioc, sent, timeout, socket))
        throw NetworkError(where + ": sending " + path + ": not sent " + within_phrase(timeout));
    if (ec) throw NetworkError(where + ": sending " + path + ": " + ec.message());

    beast::flat_buffer buffer;
    http::response_parser<http::string_body> parser;
    parser.body_limit(kBodyLimitBytes);
    bool answered = false;
    http::async_read(stream, buffer, parser, [&](boost::system::error_code e, std::size_t) {
        ec = e;
        answered = true;
    });
    if (!finish_within(ioc, answered, timeout, socket))
        throw NetworkError(where + ": the reply to " + path + ": none " + within_phrase(timeout));
    if (ec) {
        std::string why = ec.message();
        if (ec == http::error::end_of_stream || ec == net::error::eof ||
            ec == net::error::connection_reset || ec == ssl::error::stream_truncated)
            why = "the host closed the connection";
        throw NetworkError(where + ": the reply to " + path + ": " + why);
    }
    socket.shutdown(tcp::socket::shutdown_both, ec);
    auto response = parser.release();
    return {static_cast<int>(response.result_int()), std::move(response.body())};
}

}  // namespace

HttpResponse http_request(const Url& server, const HttpRequest& request,
                          std::chrono::milliseconds timeout) {
    net::io_context ioc;
    const std::string where = describe(server);
    if (!server.tls()) {
        tcp::socket socket(ioc);
        connect(ioc, socket, server, timeout, where);
        return exchange(ioc, socket, socket, server, request, timeout, where);
    }
    const auto ctx = client_context(server);
    ssl::stream<tcp::socket> stream(ioc, *ctx);
    connect(ioc, stream.next_layer(), server, timeout, where);
    tls_handshake(ioc, stream, server, timeout, where);
    return exchange(ioc, stream, stream.next_layer(), server, request, timeout, where);
}

struct WebSocketClient::State {
    virtual ~State() = default;
    virtual void send(const std::string& text) = 0;
    virtual std::optional<std::string> receive(std::chrono::milliseconds within) = 0;
};

namespace {

// A websocket over TCP (Layer tcp::socket) or over TLS on TCP (ssl::stream<tcp::socket>): the
// server's websocket and the TLS terminator's stream are the same types, built once.
template <class Layer>
struct SocketOver final : WebSocketClient::State {
    static constexpr bool kTls = !std::is_same_v<Layer, tcp::socket>;
    net::io_context ioc;
    std::unique_ptr<ssl::context> tls;  // before the stream that uses it
    std::unique_ptr<websocket::stream<Layer>> ws;
    std::string where;
    beast::flat_buffer buffer;
    bool reading = false, read_done = false;
    boost::system::error_code read_error;

    SocketOver(const Url& url, const Headers& headers, std::chrono::milliseconds timeout)
        : where(describe(url)) {
        if constexpr (kTls) {
            tls = client_context(url);
            ws = std::make_unique<websocket::stream<Layer>>(ioc, *tls);
        } else {
            ws = std::make_unique<websocket::stream<Layer>>(ioc);
        }
        tcp::socket& socket = beast::get_lowest_layer(*ws);
        connect(ioc, socket, url, timeout, where);
        if constexpr (kTls) tls_handshake(ioc, ws->next_layer(), url, timeout, where);
        ws->set_option(websocket::stream_base::decorator([headers](websocket::request_type& req) {
            req.set(http::field::user_agent, "calbox");
            for (const auto& [name, value] : headers) req.set(name, value);
        }));
        ws->read_message_max(kBodyLimitBytes);
        websocket::response_type response;
        boost::system::error_code ec;
        bool done = false;
        ws->async_handshake(response, url.host + ":" + url.port, url.path,
                            [&](boost::system::error_code e) {
                                ec = e;
                                done = true;
                            });
        if (!finish_within(ioc, done, timeout, socket))
            throw NetworkError(where + ": no websocket upgrade " + within_phrase(timeout));
        if (ec) {
            if (ec == websocket::error::upgrade_declined)
                throw NetworkError(where + ": the host refused the connection (HTTP " +
                                   std::to_string(response.result_int()) + ")");
            throw NetworkError(where + ": " + ec.message());
        }
    }

    ~SocketOver() override {
        try {
            boost::system::error_code ec;
            beast::get_lowest_layer(*ws).shutdown(tcp::socket::shutdown_both, ec);
            beast::get_lowest_layer(*ws).close(ec);
            // Pending handlers end with operation_aborted; none outlives the state they touch.
            ioc.restart();
            ioc.poll();
        } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor's clean-up, nothing to tell
        }
    }

    void send(const std::string& text) override {
        bool done = false;
        boost::system::error_code ec;
        ws->text(true);
        ws->async_write(net::buffer(text), [&](boost::system::error_code e, std::size_t) {
            ec = e;
            done = true;
        });
        if (!finish_within(ioc, done, std::chrono::seconds(30), beast::get_lowest_layer(*ws)))
            throw NetworkError(where + ": a message could not be sent within 30 s");
        if (ec) throw NetworkError(where + ": " + ec.message());
    }

    std::optional<std::string> receive(std::chrono::milliseconds within) override {
        if (!reading) {
            reading = true;
            read_done = false;
            ws->async_read(buffer, [this](boost::system::error_code e, std::size_t) {
                read_error = e;
                read_done = true;
            });
        }
        if (!run_until(ioc, read_done, Clock::now() + within)) return std::nullopt;
        reading = false;
        if (read_error) {
            const auto& e = read_error;
            const bool closed = e == websocket::error::closed || e == net::error::eof ||
                                e == net::error::connection_reset ||
                                e == ssl::error::stream_truncated;
            throw NetworkError(
                where + ": " +
                (closed ? std::string("the host closed the connection") : e.message()));
        }
        std::string message = beast::buffers_to_string(buffer.data());
        buffer.consume(buffer.size());
        return message;
    }
};

}  // namespace

WebSocketClient::WebSocketClient(const Url& url, const Headers& headers,
                                 std::chrono::milliseconds timeout) {
    if (url.tls())
        state_ = std::make_unique<SocketOver<ssl::stream<tcp::socket>>>(url, headers, timeout);
    else
        state_ = std::make_unique<SocketOver<tcp::socket>>(url, headers, timeout);
}

WebSocketClient::~WebSocketClient() = default;

void WebSocketClient::send(const std::string& text) {
    state_->send(text);
}

std::optional<std::string> WebSocketClient::receive(std::chrono::milliseconds within) {
    return state_->receive(within);
}

namespace {

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
                                                 const std::string& key_from) {
    auto context = std::make_unique<ssl::context>(ssl::context::tls_server);
    SSL_CTX_set_min_proto_version(context->native_handle(), TLS1_2_VERSION);
    boost::system::error_code ec;
    context->use_certificate_chain(net::buffer(chain_pem), ec);
    if (ec)
        throw NetworkError("TLS: " + chain_from + ": not a certificate in PEM: " + ec.message());
    context->use_private_key(net::buffer(key_pem), ssl::context::pem, ec);
    if (ec) throw NetworkError("TLS: " + key_from + ": not a private key in PEM: " + ec.message());
    if (SSL_CTX_check_private_key(context->native_handle()) != 1)
        throw NetworkError("TLS: " + key_from + " is not the key of " + chain_from);
    return context;
}

std::string pem_file_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    if (!in || !(text << in.rdbuf())) throw NetworkError("TLS: " + path + ": cannot be read");
    return text.str();
}

}  // namespace

struct HttpServer::State {
    Handlers handlers;
    ServerLimits limits;
    // The idle limit: asio retries a blocking read that SO_RCVTIMEO ends (it polls again), so a
    // watchdog shuts down each connection that has waited longer than it for a whole request.
    std::mutex idle_mutex;
    std::condition_variable idle_stop;
    bool stopping = false;                     // under idle_mutex
    std::map<int, Clock::time_point> waiting;  // by socket: since when, under idle_mutex
    std::thread watchdog;
    void waits(int fd, bool yes) {
        if (limits.idle_timeout.count() <= 0) return;
        const std::lock_guard lock(idle_mutex);
        if (yes)
            waiting[fd] = Clock::now();
        else
            waiting.erase(fd);
    }
    void watch_idle() {
        std::unique_lock lock(idle_mutex);
        while (!idle_stop.wait_for(lock, std::chrono::milliseconds(100),
                                   [this] { return stopping; })) {
            const auto now = Clock::now();
            for (auto it = waiting.begin(); it != waiting.end();) {
                if (now - it->second > limits.idle_timeout) {
                    listener->let_go(it->first);
                    it = waiting.erase(it);
                } else {
                    ++it;
                }
            }
        }
    }
    std::mutex mutex;                                         // the pushers'
    std::map<int, std::function<void(std::string)>> pushers;  // by socket, under the mutex

    std::unique_ptr<ssl::context> tls;  // null: plain HTTP

    void serve(tcp::socket accepted);
    template <class Stream>
    void serve_requests(net::io_context& ioc, Stream& stream, int fd, const std::string& peer);
    // An accepted websocket on the connection's io_context: one read always pending, writes
    // queued (the replies to each message, and whatever push() posts from other threads).
    template <class Stream>
    void serve_socket(net::io_context& ioc, Stream stream, int fd,
                      const http::request<http::string_body>& upgrade,
                      const ServerRequest& request);
    std::unique_ptr<Listener> listener;  // last: its threads use the rest
};

namespace {

ServerRequest server_request(const http::request<http::string_body>& req, const std::string& peer) {
    ServerRequest r;
    r.peer = peer;
    r.method = std::string(req.method_string());
    r.target = std::string(req.target());
    for (const auto& field : req) {
        std::string name(field.name_string());
        for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        r.headers[name] = std::string(field.value());
    }
    r.body = req.body();
    return r;
}

}  // namespace

namespace {

http::response<http::string_body> response_of(const ServerResponse& answer, bool keep_alive) {
    http::response<http::string_body> res{static_cast<http::status>(answer.status), 11};
    res.set(http::field::content_type, answer.content_type);
    for (const auto& [name, value] : answer.headers) res.set(name, value);
    res.keep_alive(keep_alive);
    res.body() = answer.body;
    res.prepare_payload();
    return res;
}

template <class Stream>
void write_answer(Stream& stream, const ServerResponse& answer, bool keep_alive,
                  boost::system::error_code& ec) {
    http::write(stream, response_of(answer, keep_alive), ec);
}

// An answer's bytes, as a connection past the limit is sent them.
std::string answer_bytes(const ServerResponse& answer) {
    std::ostringstream out;
    out << response_of(answer, false);
    return out.str();
}

// A request the parser refused: its status and why, for the client.
ServerResponse refusal(const boost::system::error_code& ec, const ServerLimits& limits) {
    if (ec == http::error::body_limit)
        return {
            413,
            "text/plain",
            "request body too large: at most " + std::to_string(limits.max_body_bytes) + " bytes\n",
            {}};
    if (ec == http::error::header_limit)
        return {431,
                "text/plain",
                "request headers too large: at most " + std::to_string(limits.max_header_bytes) +
                    " bytes\n",
                {}};
    return {400, "text/plain", "malformed request: " + ec.message() + "\n", {}};
}

// After a refusal sent while the client may still be sending (a body past the limit): the
// sending side shut down and what comes read and dropped, for at most a second, before the
// close. Closing with unread bytes resets the connection, and the client's kernel then drops the
// refusal it had not yet read.
void drain_before_close(int fd) {
    ::shutdown(fd, SHUT_WR);
    const auto give_up = Clock::now() + std::chrono::seconds(1);
    std::array<char, 16384> sink{};
    while (Clock::now() < give_up) {
        pollfd p{fd, POLLIN, 0};
        if (::poll(&p, 1, 100) < 0) return;
        if ((p.revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
        if (::recv(fd, sink.data(), sink.size(), MSG_DONTWAIT) <= 0) return;
    }
}

bool parser_refused(const boost::system::error_code& ec) {
    const boost::system::error_code parse_error = http::error::body_limit;
    return ec.category() == parse_error.category() && ec != http::error::end_of_stream &&
           ec != http::error::partial_message;
}

}  // namespace

// Each connection on an io_context of its own (a websocket's reads and writes run on it), over
// TLS when the server has a certificate: the handshake within the idle limit, like a request.
void HttpServer::State::serve(tcp::socket accepted) {
    net::io_context ioc;
    boost::system::error_code ec;
    const int fd = accepted.native_handle();
    const std::string peer = accepted.remote_endpoint(ec).address().to_string();
    tcp::socket socket(ioc);
    socket.assign(accepted.local_endpoint(ec).protocol(), accepted.release(ec), ec);
    if (ec) {
        listener->forget(fd);
        return;
    }
    if (!tls) {
        serve_requests(ioc, socket, fd, peer);
        return;
    }
    ssl::stream<tcp::socket> stream(std::move(socket), *tls);
    waits(fd, true);
    stream.handshake(ssl::stream_base::server, ec);
    waits(fd, false);
    if (ec) {
        listener->forget(fd);
        return;
    }
    serve_requests(ioc, stream, fd, peer);
    // The stream closes as it goes out of scope, no longer among the open connections.
}

template <class Stream>
void HttpServer::State::serve_requests(net::io_context& ioc, Stream& stream, int fd,
                                       const std::string& peer) {
    // No longer among the open connections before the stream closes (its descriptor's number
    // may be the next connection's at once); a websocket forgets it itself.
    struct Forget {
        Listener& listener;
        int fd;
        bool handed_on = false;
        ~Forget() {
            if (!handed_on) listener.forget(fd);
        }
    } forget{*listener, fd};
    boost::system::error_code ec;
    beast::flat_buffer buffer;
    for (;;) {
        http::request_parser<http::string_body> parser;
        parser.body_limit(limits.max_body_bytes);
        parser.header_limit(limits.max_header_bytes);
        waits(fd, true);
        http::read(stream, buffer, parser, ec);
        waits(fd, false);
        if (ec) {
            if (parser_refused(ec)) {
                write_answer(stream, refusal(ec, limits), false, ec);
                drain_before_close(fd);
            }
            return;
        }
        const auto req = parser.release();
        const ServerRequest request = server_request(req, peer);
        if (websocket::is_upgrade(req)) {
            const int status = handlers.accept_socket ? handlers.accept_socket(request) : 404;
            if (status != 101) {
                write_answer(stream,
                             {status,
                              "application/json",
                              "{\"error\": {\"code\": " + std::to_string(status) + "}}",
                              {}},
                             false, ec);
                return;
            }
            forget.handed_on = true;
            serve_socket(ioc, std::move(stream), fd, req, request);
            return;
        }
        ServerResponse answer;
        try {
            answer = handlers.http(request);
        } catch (const std::exception& e) {
            answer = {500, "text/plain", e.what(), {}};
        }
        write_answer(stream, answer, req.keep_alive(), ec);
        if (ec || !req.keep_alive()) return;
    }
}

template <class Stream>
void HttpServer::State::serve_socket(net::io_context& ioc, Stream stream, int fd,
                                     const http::request<http::string_body>& upgrade,
                                     const ServerRequest& request) {
    boost::system::error_code ec;
    websocket::stream<Stream> ws(std::move(stream));
    // No longer pushed to once this returns, before the descriptor closes with `ws` (declared
    // after it: undone before it).
    struct Forget {
        State& state;
        int fd;
        ~Forget() {
            {
                const std::lock_guard lock(state.mutex);
                state.pushers.erase(fd);
            }
            state.listener->forget(fd);
        }
    } forget{*this, fd};
    ws.read_message_max(limits.max_body_bytes);
    ws.text(true);
    std::deque<std::string> outbox;
    bool writing = false;
    beast::flat_buffer buffer;
    std::function<void()> write_next = [&] {
        if (writing || outbox.empty()) return;
        writing = true;
        ws.async_write(net::buffer(outbox.front()), [&](boost::system::error_code e, std::size_t) {
            writing = false;
            if (e) {
                ioc.stop();
                return;
            }
            outbox.pop_front();
            write_next();
        });
    };
    std::function<void()> read_next = [&] {
        ws.async_read(buffer, [&](boost::system::error_code e, std::size_t) {
            if (e) {
                ioc.stop();
                return;
            }
            const std::string message = beast::buffers_to_string(buffer.data());
            buffer.consume(buffer.size());
            try {
                for (auto& out : handlers.message(request, message))
                    outbox.push_back(std::move(out));
            } catch (const std::exception&) {
                ioc.stop();  // a handler that fails closes its socket
                return;
            }
            write_next();
            read_next();
        });
    };
    // Among the pushed-to before the handshake's answer goes: a client that acts as soon as it
    // is accepted (a box sending G-code and waiting for the terminal's lines) must not lose what
    // is pushed in between. What is pushed waits in the io_context until it runs.
    {
        const std::lock_guard lock(mutex);
        pushers[fd] = [&ioc, &outbox, &write_next](std::string m) {
            net::post(ioc, [&outbox, &write_next, m = std::move(m)]() mutable {
                outbox.push_back(std::move(m));
                write_next();
            });
        };
    }
    ws.accept(upgrade, ec);
    if (ec) return;
    read_next();
    ioc.run();
}

void HttpServer::push(const std::string& message) {
    const std::lock_guard lock(state_->mutex);
    for (auto& [fd, post] : state_->pushers) post(message);
}

HttpServer::HttpServer(const std::string& address, int port, Handlers handlers, ServerLimits limits,
                       const std::optional<hal::ServerTls>& tls)
    : state_(std::make_unique<State>()) {
    auto& s = *state_;
    s.handlers = std::move(handlers);
    s.limits = limits;
    if (tls)
        s.tls = server_tls_context(pem_file_text(tls->certificate_file), tls->certificate_file,
                                   pem_file_text(tls->key_file), tls->key_file);
    s.listener = std::make_unique<Listener>(address, port);
    if (limits.idle_timeout.count() > 0) s.watchdog = std::thread([&s] { s.watch_idle(); });
    s.listener->start([&s](tcp::socket socket) { s.serve(std::move(socket)); },
                      limits.max_connections,
                      answer_bytes({503,
                                    "text/plain",
                                    "too many connections: try again shortly\n",
                                    {{"Retry-After", "2"}}}),
                      s.tls ? s.tls->native_handle() : nullptr);
}

HttpServer::~HttpServer() {
    auto& s = *state_;
    {
        const std::lock_guard lock(s.idle_mutex);
        s.stopping = true;
    }
    s.idle_stop.notify_all();
    if (s.watchdog.joinable()) s.watchdog.join();
    s.listener->stop();
}

int HttpServer::port() const {
    return state_->listener->port();
}

void HttpServer::drop_connections() {
    state_->listener->drop_connections();
}

SelfSignedCertificate self_signed_certificate(const std::vector<std::string>& names,
                                              int valid_days) {
    if (names.empty() || valid_days <= 0)
        throw NetworkError("a certificate cannot be made: no name, or no days to be valid");
    // OpenSSL's objects, each freed with its own function.
    const std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(EVP_EC_gen("P-256"),
                                                                  EVP_PKEY_free);
    const std::unique_ptr<X509, decltype(&X509_free)> cert(X509_new(), X509_free);
    if (!key || !cert) throw NetworkError("a certificate cannot be made: out of memory");
    const auto fail = [](const char* what) {
        return NetworkError(std::string("a certificate cannot be made: ") + what);
    };
    std::random_device random;
    const auto serial = (static_cast<long>(random()) << 16) ^ static_cast<long>(random());
    if (X509_set_version(cert.get(), 2) != 1 ||
        ASN1_INTEGER_set(X509_get_serialNumber(cert.get()), serial & 0x7fffffffffffL) != 1 ||
        X509_gmtime_adj(X509_getm_notBefore(cert.get()), -3600) == nullptr ||
        X509_time_adj_ex(X509_getm_notAfter(cert.get()), valid_days, 0, nullptr) == nullptr ||
        X509_set_pubkey(cert.get(), key.get()) != 1)
        throw fail("its fields");
    X509_NAME* name = X509_get_subject_name(cert.get());
    if (X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC,
                                   reinterpret_cast<const unsigned char*>(names.front().c_str()),
                                   -1, -1, 0) != 1 ||
        X509_set_issuer_name(cert.get(), name) != 1)
        throw fail("its name");
    X509V3_CTX v3;
    X509V3_set_ctx_nodb(&v3);
    X509V3_set_ctx(&v3, cert.get(), cert.get(), nullptr, nullptr, 0);
    std::string alt;
    for (const auto& n : names) {
        boost::system::error_code not_an_address;
        net::ip::make_address(n, not_an_address);
        alt += (alt.empty() ? "" : ",") + std::string(not_an_address ? "DNS:" : "IP:") + n;
    }
    X509_EXTENSION* extension =
        X509V3_EXT_conf_nid(nullptr, &v3, NID_subject_alt_name, alt.c_str());
    if (extension == nullptr) throw fail("its subjectAltName");
    const int added = X509_add_ext(cert.get(), extension, -1);
    X509_EXTENSION_free(extension);
    if (added != 1 || X509_sign(cert.get(), key.get(), EVP_sha256()) == 0)
        throw fail("its signature");
    const auto pem = [](auto write) {
        const std::unique_ptr<BIO, decltype(&BIO_free)> bio(BIO_new(BIO_s_mem()), BIO_free);
        if (!bio || write(bio.get()) != 1) throw NetworkError("a certificate cannot be written");
        char* data = nullptr;
        const long size = BIO_get_mem_data(bio.get(), &data);
        return std::string(data, static_cast<std::size_t>(size));
    };
    SelfSignedCertificate out;
    out.certificate_pem = pem([&](BIO* b) { return PEM_write_bio_X509(b, cert.get()); });
    out.private_key_pem = pem([&](BIO* b) {
        return PEM_write_bio_PrivateKey(b, key.get(), nullptr, nullptr, 0, nullptr, nullptr);
    });
    return out;
}

hal::CertificateFacts certificate_facts(const hal::ServerTls& files) {
    const auto open = [](const std::string& path) {
        std::unique_ptr<BIO, decltype(&BIO_free)> bio(BIO_new_file(path.c_str(), "r"), BIO_free);
        if (!bio && !std::filesystem::exists(path))
            throw hal::CertificateMissing(path + ": not there");
        if (!bio) throw std::runtime_error(path + ": cannot be read");
        return bio;
    };
    const auto cert_bio = open(files.certificate_file);
    const std::unique_ptr<X509, decltype(&X509_free)> cert(
        PEM_read_bio_X509(cert_bio.get(), nullptr, nullptr, nullptr), X509_free);
    if (!cert) throw std::runtime_error(files.certificate_file + ": not a certificate in PEM");
    const auto key_bio = open(files.key_file);
    const std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(
        PEM_read_bio_PrivateKey(key_bio.get(), nullptr, nullptr, nullptr), EVP_PKEY_free);
    if (!key) throw std::runtime_error(files.key_file + ": not a private key in PEM");
    if (X509_check_private_key(cert.get(), key.get()) != 1)
        throw std::runtime_error(files.key_file + ": not the key of " + files.certificate_file);
    hal::CertificateFacts facts;
    std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
    unsigned int length = 0;
    if (X509_digest(cert.get(), EVP_sha256(), digest.data(), &length) != 1)
        throw std::runtime_error(files.certificate_file + ": its fingerprint cannot be taken");
    static const char* const kHex = "0123456789ABCDEF";
    for (unsigned int i = 0; i < length; ++i) {
        if (i > 0) facts.sha256_fingerprint += ':';
        facts.sha256_fingerprint += kHex[digest[i] >> 4];
        facts.sha256_fingerprint += kHex[digest[i] & 15];
    }
    std::array<char, 256> common_name{};
    if (X509_NAME_get_text_by_NID(X509_get_subject_name(cert.get()), NID_commonName,
                                  common_name.data(), static_cast<int>(common_name.size())) > 0)
        facts.subject = common_name.data();
    std::tm until{};
    if (ASN1_TIME_to_tm(X509_get0_notAfter(cert.get()), &until) != 1)
        throw std::runtime_error(files.certificate_file + ": its expiry cannot be read");
    facts.not_after_unix_s = static_cast<std::int64_t>(timegm(&until));
    return facts;
}

struct TlsTerminator::State {
    std::unique_ptr<ssl::context> tls;
    int inner_port = 0;
    std::unique_ptr<Listener> listener;  // last: its threads use the rest

    void pass_through(tcp::socket accepted);
};

// One connection on an io_context of its own: the TLS handshake, a connection to the inner
// server, then bytes both ways until either side ends.
void TlsTerminator::State::pass_through(tcp::socket accepted) {
    net::io_context own;
    boost::system::error_code ec;
    const int outer_fd = accepted.native_handle();
    tcp::socket outer(own);
    outer.assign(accepted.local_endpoint(ec).protocol(), accepted.release(ec), ec);
    ssl::stream<tcp::socket> client(std::move(outer), *tls);
    tcp::socket inner(own);
    struct Forget {
        Listener& listener;
        std::vector<int> fds;
        ~Forget() {
            for (const int fd : fds) listener.forget(fd);
        }
    } forget{*listener, {outer_fd}};
    if (ec) return;
    client.handshake(ssl::stream_base::server, ec);
    if (ec) return;
    inner.connect(
        tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(inner_port)),
        ec);
    if (ec) return;
    if (!listener->track(inner.native_handle())) return;
    forget.fds.push_back(inner.native_handle());
    std::array<char, 16384> up{}, down{};
    const auto end = [&] {
        boost::system::error_code ignored;
        client.lowest_layer().shutdown(tcp::socket::shutdown_both, ignored);
        inner.shutdown(tcp::socket::shutdown_both, ignored);
        own.stop();
    };
    std::function<void()> upstream = [&] {
        client.async_read_some(net::buffer(up), [&](boost::system::error_code e, std::size_t n) {
            if (e) return end();
            net::async_write(inner, net::buffer(up.data(), n),
                             [&](boost::system::error_code w, std::size_t) {
                                 if (w) return end();
                                 upstream();
                             });
        });
    };
    std::function<void()> downstream = [&] {
        inner.async_read_some(net::buffer(down), [&](boost::system::error_code e, std::size_t n) {
            if (e) return end();
            net::async_write(client, net::buffer(down.data(), n),
                             [&](boost::system::error_code w, std::size_t) {
                                 if (w) return end();
                                 downstream();
                             });
        });
    };
    upstream();
    downstream();
    own.run();
}

TlsTerminator::TlsTerminator(const std::string& address, int inner_port,
                             const SelfSignedCertificate& certificate)
    : state_(std::make_unique<State>()) {
    auto& s = *state_;
    s.inner_port = inner_port;
    s.tls = server_tls_context(certificate.certificate_pem, "the certificate",
                               certificate.private_key_pem, "its key");
    s.listener = std::make_unique<Listener>(address, 0);
    s.listener->start([&s](tcp::socket socket) { s.pass_through(std::move(socket)); });
}

TlsTerminator::~TlsTerminator() {
    state_->listener->stop();
}

int TlsTerminator::port() const {
    return state_->listener->port();
}

}  // namespace calbox::drivers
