#include "drivers/http_server.hpp"

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

#include "drivers/asio_names.hpp"
#include "drivers/tcp_listener.hpp"

namespace calbox::drivers {

using listening::Listener;
using listening::pem_file_text;
using listening::server_tls_context;

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

}  // namespace calbox::drivers
