#include "drivers/network.hpp"

#include "drivers/http.hpp"
#include "drivers/mqtt_client.hpp"
#include "drivers/password.hpp"

namespace calbox::drivers {
namespace {

class SystemHttp final : public hal::HttpClient {
  public:
    hal::HttpResponse request(const net::Url& server, const hal::HttpRequest& request,
                              std::chrono::milliseconds timeout) override {
        return http_request(server, request, timeout);
    }
    std::unique_ptr<hal::WebSocket> open_socket(const net::Url& url, const hal::Headers& headers,
                                                std::chrono::milliseconds timeout) override {
        return std::make_unique<WebSocketClient>(url, headers, timeout);
    }
};

class SystemNetwork final : public hal::Network {
  public:
    hal::HttpClient& http() override { return http_; }
    std::unique_ptr<hal::HttpListener> listen(const std::string& address, int port,
                                              hal::HttpHandlers handlers,
                                              hal::ServerLimits limits) override {
        return std::make_unique<HttpServer>(address, port, std::move(handlers), limits);
    }
    std::unique_ptr<hal::MqttSession> mqtt(const std::string& client_id,
                                           const hal::MqttBroker& broker, hal::MqttWill will,
                                           hal::MqttCallbacks callbacks) override {
        return std::make_unique<MqttClient>(client_id, broker, std::move(will),
                                            std::move(callbacks));
    }
    hal::PasswordHasher& passwords() override { return passwords_; }

  private:
    SystemHttp http_;
    Pbkdf2Hasher passwords_;
};

}  // namespace

std::unique_ptr<hal::Network> system_network() {
    return std::make_unique<SystemNetwork>();
}

}  // namespace calbox::drivers
