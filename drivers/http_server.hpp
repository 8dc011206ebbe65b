#pragma once
// hal/http.hpp's server: a small threaded one for the box's web page and for the twins that
// stand in for the printers' hosts on the sim board, with its limits (connections, idle time,
// sizes) and the answers it refuses with.
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
using calbox::net::Url;

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

}  // namespace calbox::drivers
