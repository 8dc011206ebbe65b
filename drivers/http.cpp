#include "drivers/http.hpp"

#include <sys/socket.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <cctype>
#include <deque>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>

namespace calbox::drivers {
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
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

std::string describe(const Url& url) {
    return url.origin();
}

}  // namespace

Url parse_url(const std::string& text) {
    Url url;
    const std::size_t colon = text.find("://");
    if (colon == std::string::npos)
        throw std::invalid_argument("'" + text + "' is not a URL (http://HOST:PORT)");
    url.scheme = text.substr(0, colon);
    for (auto& c : url.scheme) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (url.scheme == "https" || url.scheme == "wss")
        throw std::invalid_argument("'" + text +
                                    "': TLS is not supported yet; reach the host over http on "
                                    "the local network");
    if (url.scheme != "http" && url.scheme != "ws")
        throw std::invalid_argument("'" + text + "': the scheme must be http or ws");
    std::string rest = text.substr(colon + 3);
    const std::size_t slash = rest.find('/');
    url.path = slash == std::string::npos ? "/" : rest.substr(slash);
    std::string authority = slash == std::string::npos ? rest : rest.substr(0, slash);
    if (authority.find('@') != std::string::npos)
        throw std::invalid_argument("'" + text +
                                    "': no user or password in the URL (the key goes in its file)");
    const std::size_t port_at = authority.rfind(':');
    if (port_at != std::string::npos && authority.find(']') == std::string::npos) {
        url.port = authority.substr(port_at + 1);
        authority.resize(port_at);
    } else {
        url.port = "80";
    }
    url.host = authority;
    if (url.host.empty()) throw std::invalid_argument("'" + text + "': no host");
    int port = 0;
    for (char c : url.port) {
        if (!std::isdigit(static_cast<unsigned char>(c)))
            throw std::invalid_argument("'" + text + "': the port is not a number");
        port = port * 10 + (c - '0');
        if (port > 65535) break;
    }
    if (url.port.empty() || port < 1 || port > 65535)
        throw std::invalid_argument("'" + text + "': the port must be 1 to 65535");
    return url;
}

HttpResponse http_request(const Url& server, const HttpRequest& request,
                          std::chrono::milliseconds timeout) {
    net::io_context ioc;
    beast::tcp_stream stream(ioc);
    const std::string where = describe(server);
    boost::system::error_code ec;
    tcp::resolver resolver(ioc);
    const auto endpoints = resolver.resolve(server.host, server.port, ec);
    if (ec) throw NetworkError(where + ": " + ec.message());
    stream.expires_after(timeout);
    bool done = false;
    stream.async_connect(endpoints, [&](boost::system::error_code e, const tcp::endpoint&) {
        ec = e;
        done = true;
    });
    ioc.run();
    if (ec) throw NetworkError(where + ": " + ec.message());

    http::request<http::string_body> req{http::string_to_verb(request.method), request.target, 11};
    if (req.method() == http::verb::unknown)
        throw std::invalid_argument("HTTP method '" + request.method + "'");
    req.set(http::field::host, server.host);
    req.set(http::field::user_agent, "calbox");
    for (const auto& [name, value] : request.headers) req.set(name, value);
    if (!request.content_type.empty()) req.set(http::field::content_type, request.content_type);
    req.body() = request.body;
    req.prepare_payload();
    stream.expires_after(timeout);
    done = false;
    http::async_write(stream, req, [&](boost::system::error_code e, std::size_t) {
        ec = e;
        done = true;
    });
    ioc.restart();
    ioc.run();
    // The path alone in what is said: a query may carry a password (rr_connect's).
    const std::string path = request.target.substr(0, request.target.find('?'));
    if (ec) throw NetworkError(where + ": sending " + path + ": " + ec.message());

    beast::flat_buffer buffer;
    http::response_parser<http::string_body> parser;
    parser.body_limit(kBodyLimitBytes);
    stream.expires_after(timeout);
    http::async_read(stream, buffer, parser, [&](boost::system::error_code e, std::size_t) {
        ec = e;
        done = true;
    });
    ioc.restart();
    ioc.run();
    if (ec) {
        std::string why = ec.message();
        if (ec == beast::error::timeout)
            why = "none within " + std::to_string(timeout.count()) + " ms";
        else if (ec == http::error::end_of_stream || ec == net::error::eof ||
                 ec == net::error::connection_reset)
            why = "the host closed the connection";
        throw NetworkError(where + ": the reply to " + path + ": " + why);
    }
    stream.socket().shutdown(tcp::socket::shutdown_both, ec);
    auto response = parser.release();
    return {static_cast<int>(response.result_int()), std::move(response.body())};
}

FormBody multipart_form(const std::string& file_field, const std::string& file_name,
                        const std::string& file_contents, const Headers& fields) {
    // A boundary that the contents do not hold.
    std::mt19937_64 random(std::random_device{}());
    std::string boundary;
    do {
        boundary = "calbox-" + std::to_string(random());
    } while (file_contents.find(boundary) != std::string::npos);
    std::string body;
    const auto part = [&body, &boundary](const std::string& disposition) {
        body.append("--").append(boundary).append("\r\nContent-Disposition: form-data; ");
        body.append(disposition);
    };
    for (const auto& [name, value] : fields) {
        part("name=\"" + name + "\"\r\n\r\n");
        body.append(value).append("\r\n");
    }
    part("name=\"" + file_field + "\"; filename=\"" + file_name +
         "\"\r\nContent-Type: application/octet-stream\r\n\r\n");
    body.append(file_contents).append("\r\n--").append(boundary).append("--\r\n");
    return {"multipart/form-data; boundary=" + boundary, std::move(body)};
}

struct WebSocketClient::State {
    net::io_context ioc;
    websocket::stream<beast::tcp_stream> ws{ioc};
    std::string where;
    beast::flat_buffer buffer;
    bool reading = false, read_done = false;
    boost::system::error_code read_error;
};

WebSocketClient::WebSocketClient(const Url& url, const Headers& headers,
                                 std::chrono::milliseconds timeout)
    : state_(std::make_unique<State>()) {
    auto& s = *state_;
    s.where = describe(url);
    boost::system::error_code ec;
    tcp::resolver resolver(s.ioc);
    const auto endpoints = resolver.resolve(url.host, url.port, ec);
    if (ec) throw NetworkError(s.where + ": " + ec.message());
    auto& tcp_layer = beast::get_lowest_layer(s.ws);
    tcp_layer.expires_after(timeout);
    bool done = false;
    tcp_layer.async_connect(endpoints, [&](boost::system::error_code e, const tcp::endpoint&) {
        ec = e;
        done = true;
    });
    s.ioc.run();
    if (ec) throw NetworkError(s.where + ": " + ec.message());
    s.ws.set_option(websocket::stream_base::decorator([headers](websocket::request_type& req) {
        req.set(http::field::user_agent, "calbox");
        for (const auto& [name, value] : headers) req.set(name, value);
    }));
    s.ws.read_message_max(kBodyLimitBytes);
    websocket::response_type response;
    done = false;
    s.ws.async_handshake(response, url.host + ":" + url.port, url.path,
                         [&](boost::system::error_code e) {
                             ec = e;
                             done = true;
                         });
    s.ioc.restart();
    s.ioc.run();
    if (ec) {
        if (ec == websocket::error::upgrade_declined)
            throw NetworkError(s.where + ": the host refused the connection (HTTP " +
                               std::to_string(response.result_int()) + ")");
        throw NetworkError(s.where + ": " + ec.message());
    }
    // From here each call keeps its own deadline.
    tcp_layer.expires_never();
}

WebSocketClient::~WebSocketClient() {
    try {
        boost::system::error_code ec;
        beast::get_lowest_layer(state_->ws).socket().shutdown(tcp::socket::shutdown_both, ec);
        beast::get_lowest_layer(state_->ws).socket().close(ec);
        // Pending handlers end with operation_aborted; none outlives the state they touch.
        state_->ioc.restart();
        state_->ioc.poll();
    } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor's clean-up, nothing to tell
    }
}

void WebSocketClient::send(const std::string& text) {
    auto& s = *state_;
    bool done = false;
    boost::system::error_code ec;
    s.ws.text(true);
    s.ws.async_write(net::buffer(text), [&](boost::system::error_code e, std::size_t) {
        ec = e;
        done = true;
    });
    if (!run_until(s.ioc, done, Clock::now() + std::chrono::seconds(30))) {
        beast::get_lowest_layer(s.ws).socket().close(ec);
        s.ioc.restart();
        s.ioc.poll();
        throw NetworkError(s.where + ": a message could not be sent within 30 s");
    }
    if (ec) throw NetworkError(s.where + ": " + ec.message());
}

std::optional<std::string> WebSocketClient::receive(std::chrono::milliseconds within) {
    auto& s = *state_;
    if (!s.reading) {
        s.reading = true;
        s.read_done = false;
        s.ws.async_read(s.buffer, [&s](boost::system::error_code e, std::size_t) {
            s.read_error = e;
            s.read_done = true;
        });
    }
    if (!run_until(s.ioc, s.read_done, Clock::now() + within)) return std::nullopt;
    s.reading = false;
    if (s.read_error) {
        const auto& e = s.read_error;
        const bool closed = e == websocket::error::closed || e == net::error::eof ||
                            e == net::error::connection_reset || e == beast::error::timeout;
        throw NetworkError(s.where + ": " +
                           (closed ? std::string("the host closed the connection") : e.message()));
    }
    std::string message = beast::buffers_to_string(s.buffer.data());
    s.buffer.consume(s.buffer.size());
    return message;
}

struct HttpServer::State {
    Handlers handlers;
    net::io_context ioc;
    tcp::acceptor acceptor{ioc};
    int port = 0;
    std::mutex mutex;
    std::set<int> open_fds;
    std::vector<std::thread> connections;
    std::thread accepting;
    bool stopping = false;

    void serve(tcp::socket socket);
    // An accepted websocket on an io_context of its own: one read always pending, writes queued
    // (the replies to each message, and whatever push() posts from other threads).
    void serve_socket(tcp::socket socket, const http::request<http::string_body>& upgrade,
                      const ServerRequest& request);
    std::map<int, std::function<void(std::string)>> pushers;  // by socket, under the mutex
};

namespace {

ServerRequest server_request(const http::request<http::string_body>& req) {
    ServerRequest r;
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

void HttpServer::State::serve(tcp::socket socket) {
    const int fd = socket.native_handle();
    boost::system::error_code ec;
    beast::flat_buffer buffer;
    for (;;) {
        http::request_parser<http::string_body> parser;
        parser.body_limit(kBodyLimitBytes);
        http::read(socket, buffer, parser, ec);
        if (ec) break;
        const auto req = parser.release();
        const ServerRequest request = server_request(req);
        if (websocket::is_upgrade(req)) {
            const int status = handlers.accept_socket ? handlers.accept_socket(request) : 404;
            if (status != 101) {
                http::response<http::string_body> res{static_cast<http::status>(status), 11};
                res.body() = "{\"error\": {\"code\": " + std::to_string(status) + "}}";
                res.prepare_payload();
                http::write(socket, res, ec);
                break;
            }
            // It closes the socket itself, once it is no longer among the open ones.
            serve_socket(std::move(socket), req, request);
            return;
        }
        ServerResponse answer;
        try {
            answer = handlers.http(request);
        } catch (const std::exception& e) {
            answer = {500, "text/plain", e.what()};
        }
        http::response<http::string_body> res{static_cast<http::status>(answer.status), 11};
        res.set(http::field::content_type, answer.content_type);
        res.keep_alive(req.keep_alive());
        res.body() = answer.body;
        res.prepare_payload();
        http::write(socket, res, ec);
        if (ec || !req.keep_alive()) break;
    }
    const std::lock_guard lock(mutex);
    open_fds.erase(fd);
    // The socket (or the stream it moved into) closes as it goes out of scope.
}

void HttpServer::State::serve_socket(tcp::socket accepted,
                                     const http::request<http::string_body>& upgrade,
                                     const ServerRequest& request) {
    net::io_context ioc;
    boost::system::error_code ec;
    const int fd = accepted.native_handle();
    tcp::socket own(ioc);
    const auto protocol = accepted.local_endpoint(ec).protocol();
    own.assign(protocol, accepted.release(ec), ec);
    websocket::stream<tcp::socket> ws(std::move(own));
    // No longer among the open ones once this returns, before the descriptor closes with `ws`
    // (declared after it: undone before it).
    struct Forget {
        State& state;
        int fd;
        ~Forget() {
            const std::lock_guard lock(state.mutex);
            state.pushers.erase(fd);
            state.open_fds.erase(fd);
        }
    } forget{*this, fd};
    if (ec) return;
    ws.read_message_max(kBodyLimitBytes);
    ws.accept(upgrade, ec);
    if (ec) return;
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
    {
        const std::lock_guard lock(mutex);
        pushers[fd] = [&ioc, &outbox, &write_next](std::string m) {
            net::post(ioc, [&outbox, &write_next, m = std::move(m)]() mutable {
                outbox.push_back(std::move(m));
                write_next();
            });
        };
    }
    read_next();
    ioc.run();
}

void HttpServer::push(const std::string& message) {
    const std::lock_guard lock(state_->mutex);
    for (auto& [fd, post] : state_->pushers) post(message);
}

HttpServer::HttpServer(const std::string& address, int port, Handlers handlers)
    : state_(std::make_unique<State>()) {
    auto& s = *state_;
    s.handlers = std::move(handlers);
    boost::system::error_code ec;
    const tcp::endpoint at(net::ip::make_address(address, ec), static_cast<unsigned short>(port));
    if (ec) throw NetworkError(address + ": " + ec.message());
    s.acceptor.open(at.protocol(), ec);
    if (!ec) s.acceptor.set_option(net::socket_base::reuse_address(true), ec);
    if (!ec) s.acceptor.bind(at, ec);
    if (!ec) s.acceptor.listen(net::socket_base::max_listen_connections, ec);
    if (ec)
        throw NetworkError(address + ":" + std::to_string(port) +
                           ": cannot listen: " + ec.message());
    s.port = s.acceptor.local_endpoint().port();
    s.accepting = std::thread([&s] {
        for (;;) {
            boost::system::error_code e;
            tcp::socket socket(s.ioc);
            s.acceptor.accept(socket, e);
            const std::lock_guard lock(s.mutex);
            if (s.stopping) return;
            if (e) continue;
            s.open_fds.insert(socket.native_handle());
            s.connections.emplace_back(
                [&s, socket = std::move(socket)]() mutable { s.serve(std::move(socket)); });
        }
    });
}

HttpServer::~HttpServer() {
    auto& s = *state_;
    {
        const std::lock_guard lock(s.mutex);
        s.stopping = true;
        // A blocked accept() returns once its socket is shut down.
        ::shutdown(s.acceptor.native_handle(), SHUT_RDWR);
    }
    s.accepting.join();
    drop_connections();
    for (auto& t : s.connections) t.join();
}

int HttpServer::port() const {
    return state_->port;
}

void HttpServer::drop_connections() {
    const std::lock_guard lock(state_->mutex);
    for (int fd : state_->open_fds) ::shutdown(fd, SHUT_RDWR);
}

}  // namespace calbox::drivers
