#pragma once
// HTTP and WebSocket, as the box's links to a printer's host and its own web page use them: a
// client (a request answered within a timeout, a websocket), and a listener serving requests
// on a port. Blocking calls are made off the event loop (a worker's thread); a listener calls its
// handlers on threads of its own.
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/net/endpoints.hpp"
#include "core/net/http_text.hpp"

namespace calbox::hal {

using net::Headers;

// A connection refused, a name not found, a timeout, a peer that closed: what, with the reason.
class NetworkError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct HttpRequest {
    std::string method = "GET";
    std::string target;  // "/server/info?x=1"
    Headers headers;
    std::string content_type;
    std::string body;
};
struct HttpResponse {
    int status = 0;
    std::string body;
};

class WebSocket {
  public:
    virtual ~WebSocket() = default;
    virtual void send(const std::string& text) = 0;  // throws NetworkError
    // The next message, or nothing within `within` (the read goes on at the next call). Throws
    // NetworkError when the connection is gone.
    virtual std::optional<std::string> receive(std::chrono::milliseconds within) = 0;
};

// Safe to call from several threads at once: each call has a connection of its own.
class HttpClient {
  public:
    virtual ~HttpClient() = default;
    // One request, answered within `timeout`. Throws NetworkError.
    virtual HttpResponse request(const net::Url& server, const HttpRequest& request,
                                 std::chrono::milliseconds timeout) = 0;
    // Connects and upgrades within `timeout`; throws NetworkError (a refused upgrade names the
    // HTTP status the server gave).
    virtual std::unique_ptr<WebSocket> open_socket(const net::Url& url, const Headers& headers,
                                                   std::chrono::milliseconds timeout) = 0;
};

// What a listener is asked: header names in lower case; `peer` is the client's address.
struct ServerRequest {
    std::string method, target;
    std::map<std::string, std::string> headers;
    std::string body;
    std::string peer;
};
struct ServerResponse {
    int status = 200;
    std::string content_type = "application/json";
    std::string body;
    Headers headers{};  // more than the content type and length
};

// What one listener takes before it refuses, each with its status: a body past max_body_bytes
// (413), headers past max_header_bytes (431), a request that does not parse (400), a connection
// past max_connections (503, closed at once). A connection silent for idle_timeout is closed, so
// that a client that opens and never finishes holds no thread for long. Zero: no limit.
struct ServerLimits {
    std::uint64_t max_body_bytes = 64ull << 20;
    std::uint32_t max_header_bytes = 16u << 10;
    int max_connections = 0;
    std::chrono::milliseconds idle_timeout{0};
};

// TLS on a listener: its certificate (the chain, PEM, the server's first) and private key, as
// files.
struct ServerTls {
    std::string certificate_file, key_file;
};

// Each is called on the connection's thread: they must be thread-safe.
struct HttpHandlers {
    std::function<ServerResponse(const ServerRequest&)> http;
    // An upgrade: 101 accepts it, any other status refuses it so.
    std::function<int(const ServerRequest&)> accept_socket;
    // One message on an accepted socket: the messages to send back, in order.
    std::function<std::vector<std::string>(const ServerRequest& upgrade,
                                           const std::string& message)>
        message;
};

// Serving on a port until destroyed (every connection closed, its thread joined).
class HttpListener {
  public:
    virtual ~HttpListener() = default;
    virtual int port() const = 0;  // the one listened on (useful with port 0)
    // Sends `message` on every open websocket: any thread.
    virtual void push(const std::string& message) = 0;
};

}  // namespace calbox::hal
