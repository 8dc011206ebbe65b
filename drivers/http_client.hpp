#pragma once
// hal/http.hpp's client over TCP and TLS, through Boost.Beast and OpenSSL (kept out of this
// header: they are heavy to compile): the links to a printer's host use it, requests and
// websockets.
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

    struct State;  // over TCP or TLS (drivers/http_client.cpp)

  private:
    std::unique_ptr<State> state_;
};

}  // namespace calbox::drivers
