#include "drivers/http_client.hpp"

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

namespace calbox::drivers {

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

}  // namespace calbox::drivers
