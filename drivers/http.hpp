#pragma once
// HTTP and WebSocket over TCP, through Boost.Beast (kept out of this header: it is heavy to
// compile): a client for the hosts that own a printer (Moonraker), and a small threaded server
// for the twin that stands in for them on the sim board.
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace calbox::drivers {

// A connection refused, a name not found, a timeout, a peer that closed: what, with the reason.
class NetworkError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// "http://host:port/path", "https://...", "ws://..." or "wss://...": parsed once. Throws
// std::invalid_argument naming what is wrong.
struct Url {
    std::string scheme, host, port, path;
    // Over TLS: the certificate authorities that vouch for the host, a PEM file (empty: the
    // system's). The host's certificate must name the URL's host.
    std::string ca_file;
    bool tls() const { return scheme == "https" || scheme == "wss"; }
    std::string origin() const { return scheme + "://" + host + ":" + port; }
};
Url parse_url(const std::string& text);

// "HOST:PORT" ("[::1]:8080" for IPv6), the port 0 to 65535. With `names` false the host must
// be an IP address ("localhost" is 127.0.0.1): a server binds to one. Throws
// std::invalid_argument naming what is wrong.
struct HostPort {
    std::string host;
    int port = 0;
};
HostPort parse_host_port(const std::string& text, bool names);

using Headers = std::vector<std::pair<std::string, std::string>>;

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

// One request on a connection of its own, answered within `timeout`. Throws NetworkError.
HttpResponse http_request(const Url& server, const HttpRequest& request,
                          std::chrono::milliseconds timeout);

// A multipart/form-data body holding one file (an upload's "file" field) and plain fields.
struct FormBody {
    std::string content_type, body;
};
FormBody multipart_form(const std::string& file_field, const std::string& file_name,
                        const std::string& file_contents, const Headers& fields = {});

class WebSocketClient {
  public:
    // Connects and upgrades within `timeout`; throws NetworkError (a refused upgrade names the
    // HTTP status the server gave).
    WebSocketClient(const Url& url, const Headers& headers, std::chrono::milliseconds timeout);
    WebSocketClient(const WebSocketClient&) = delete;
    WebSocketClient& operator=(const WebSocketClient&) = delete;
    ~WebSocketClient();
    void send(const std::string& text);  // throws NetworkError
    // The next message, or nothing within `within` (the read goes on at the next call). Throws
    // NetworkError when the connection is gone.
    std::optional<std::string> receive(std::chrono::milliseconds within);

    struct State;  // over TCP or TLS (drivers/http.cpp)

  private:
    std::unique_ptr<State> state_;
};

// What a server is asked: header names in lower case; `peer` is the client's address.
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

// What one server takes before it refuses, each with its status: a body past max_body_bytes
// (413), headers past max_header_bytes (431), a request that does not parse (400), a connection
// past max_connections (503, closed at once). A connection silent for idle_timeout is closed, so
// that a client that opens and never finishes holds no thread for long. Zero: no limit.
struct ServerLimits {
    std::uint64_t max_body_bytes = 64ull << 20;
    std::uint32_t max_header_bytes = 16u << 10;
    int max_connections = 0;
    std::chrono::milliseconds idle_timeout{0};
};

// Serves HTTP and WebSocket on one port of `address`, a thread per connection (joined as soon as
// it ends). Each handler is called on the connection's thread (they must be thread-safe).
class HttpServer {
  public:
    struct Handlers {
        std::function<ServerResponse(const ServerRequest&)> http;
        // An upgrade: 101 accepts it, any other status refuses it so.
        std::function<int(const ServerRequest&)> accept_socket;
        // One message on an accepted socket: the messages to send back, in order.
        std::function<std::vector<std::string>(const ServerRequest& upgrade,
                                               const std::string& message)>
            message;
    };
    // Port 0 takes a free one (port()). Throws NetworkError when it cannot listen.
    HttpServer(const std::string& address, int port, Handlers handlers, ServerLimits limits = {});
    HttpServer(const HttpServer&) = delete;
    HttpServer& operator=(const HttpServer&) = delete;
    ~HttpServer();  // closes every connection and waits for its thread
    int port() const;
    // Closes every open connection (a host restarting): clients see them gone.
    void drop_connections();
    // Sends `message` on every open websocket (a host's push: OctoPrint's terminal logs).
    void push(const std::string& message);

  private:
    struct State;
    std::unique_ptr<State> state_;
};

// A certificate of its own making for `ip_address` (subject and subjectAltName), valid a day:
// PEM texts. For a server whose clients are given the certificate itself to trust (the twin's
// hosts on loopback).
struct SelfSignedCertificate {
    std::string certificate_pem, private_key_pem;
};
SelfSignedCertificate self_signed_certificate(const std::string& ip_address);

// TLS on a port of `address` in front of a plain server on 127.0.0.1:`inner_port`, as a reverse
// proxy in front of a printer's host (nginx before Moonraker) serves it: each connection's bytes
// passed through both ways, a connection the inner server drops dropped too.
class TlsTerminator {
  public:
    // Port 0 takes a free one (port()). Throws NetworkError when it cannot listen or the
    // certificate does not load.
    TlsTerminator(const std::string& address, int inner_port,
                  const SelfSignedCertificate& certificate);
    TlsTerminator(const TlsTerminator&) = delete;
    TlsTerminator& operator=(const TlsTerminator&) = delete;
    ~TlsTerminator();  // closes every connection and waits for its thread
    int port() const;

  private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace calbox::drivers
