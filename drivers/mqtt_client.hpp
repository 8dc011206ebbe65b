#pragma once
// hal::MqttSession over libmosquitto, on a network thread of its own: it connects in the background
// with a last will (as a user, over TLS where the broker says), reconnects with back-off (1 s
// doubling to 60 s) whenever the broker is not there, goes or refuses it, and never blocks its
// caller. Callbacks run on that thread.
#include <functional>
#include <memory>
#include <string>

#include "hal/mqtt.hpp"

namespace calbox::drivers {

using hal::MqttWill;

class MqttClient final : public hal::MqttSession {
  public:
    using Callbacks = hal::MqttCallbacks;
    // Starts connecting at once. Throws std::runtime_error when libmosquitto cannot start (out of
    // memory, no thread) or the login cannot be tried (hal::Network::mqtt).
    MqttClient(const std::string& client_id, const hal::MqttBroker& broker, MqttWill will,
               Callbacks callbacks);
    MqttClient(const MqttClient&) = delete;
    MqttClient& operator=(const MqttClient&) = delete;
    // Says the will's goodbye (retained) if connected, disconnects, joins.
    ~MqttClient() override;
    void publish(const std::string& topic, const std::string& payload, bool retain) override;
    void subscribe(const std::string& topic) override;
    bool connected() const override;

    struct State;

  private:
    std::unique_ptr<State> state_;
};

}  // namespace calbox::drivers
