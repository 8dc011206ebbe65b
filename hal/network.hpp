#pragma once
// What the network gives the appliance, opened by a board (board::network()) as it opens ports
// and Modbus roles: an HTTP client, listeners, MQTT sessions, and the password hasher of the web
// page's password.
#include <memory>
#include <string>

#include "hal/http.hpp"
#include "hal/mqtt.hpp"
#include "hal/password.hpp"

namespace calbox::hal {

class Network {
  public:
    virtual ~Network() = default;
    virtual HttpClient& http() = 0;
    // Serves on `port` of `address` (an IP address; port 0 takes a free one). Throws
    // NetworkError when it cannot listen.
    virtual std::unique_ptr<HttpListener> listen(const std::string& address, int port,
                                                 HttpHandlers handlers, ServerLimits limits) = 0;
    // Starts connecting at once. Throws std::runtime_error when the session cannot start or its
    // login cannot be tried at all (the password's file missing, empty or readable by others; a
    // CA file TLS cannot load).
    virtual std::unique_ptr<MqttSession> mqtt(const std::string& client_id,
                                              const MqttBroker& broker, MqttWill will,
                                              MqttCallbacks callbacks) = 0;
    virtual PasswordHasher& passwords() = 0;
};

}  // namespace calbox::hal
