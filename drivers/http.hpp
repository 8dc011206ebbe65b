#pragma once
// hal/http.hpp over TCP and TLS, through Boost.Beast and OpenSSL (kept out of this header: they
// are heavy to compile): the client the links to a printer's host use, and a small threaded
// server for the box's web page and for the twins that stand in for the hosts on the sim board.
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

#include "core/net/endpoints.hpp"
#include "hal/http.hpp"
#include "hal/network.hpp"

namespace calbox::drivers {

using hal::Headers;
using hal::HttpRequest;
using hal::HttpResponse;
using hal::NetworkError;
using hal::ServerLimits;
using hal::ServerRequest;
using hal::ServerResponse;
using net::Url;

// One request on a connection of its own, answered within `timeout`. Throws NetworkError.
HttpResponse http_request(const Url& server, const HttpRequest& request,
                          std::chrono::milliseconds timeout);

class WebSocketClient final : public hal::WebSocket {
  public:
    // Connects and upgrades within `timeout`; throws NetworkError (a refused upgrade names the
    // HTTP status the server gave).
    WebSocketClient(const Url& url, const Headers& headers, std::chrono::milliseconds timeout);
    WebSocketClient(const WebSocketClient&) = delete;
    WebSocketClient& operator=(const WebSocketClient&) = delete;
    ~WebSocketClient() override;
    void send(const std::string& text) override;
    std::optional<std::string> receive(std::chrono::milliseconds within) override;

    struct State;  // over TCP or TLS (drivers/http.cpp)

  private:
    std::unique_ptr<State> state_;
};

// Serves HTTP and WebSocket on one port of `address`, a thread per connection (joined as soon as
// it ends). Each handler is called on the connection's thread (they must be thread-safe).
class HttpServer final : public hal::HttpListener {
  public:
    using Handlers = hal::HttpHandlers;
    // Port 0 takes a free one (port()); over TLS with `tls`. Throws NetworkError when it cannot
    // listen or the certificate's files do not load.
    HttpServer(const std::string& address, int port, Handlers handlers, ServerLimits limits = {},
               const std::optional<hal::ServerTls>& tls = std::nullopt);
    HttpServer(const HttpServer&) = delete;
    HttpServer& operator=(const HttpServer&) = delete;
    ~HttpServer() override;  // closes every connection and waits for its thread
    int port() const override;
    // Closes every open connection (a host restarting): clients see them gone.
    void drop_connections();
    // A host's push too (OctoPrint's terminal logs).
    void push(const std::string& message) override;

  private:
    struct State;
    std::unique_ptr<State> state_;
};

// A certificate of its own making for `names` (IP addresses and host names, each in its
// subjectAltName; the first its subject), valid `valid_days` from an hour ago: PEM texts. For a
// server whose clients are given the certificate itself to trust, or check its fingerprint (the
// twin's hosts on loopback, the box's own page).
struct SelfSignedCertificate {
    std::string certificate_pem, private_key_pem;
};
SelfSignedCertificate self_signed_certificate(const std::vector<std::string>& names,
                                              int valid_days);

// The facts of a certificate and key pair in PEM files, the key checked against the certificate.
// Throws std::runtime_error naming the file and what is wrong with it.
hal::CertificateFacts certificate_facts(const hal::ServerTls& files);

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
