#pragma once
// An MQTT client over libmosquitto, on the library's own network thread: it connects in the
// background with a last will, reconnects with back-off (1 s doubling to 60 s) whenever the broker
// goes or refuses it, and never blocks its caller. Callbacks run on that thread.
#include <functional>
#include <memory>
#include <string>

namespace calbox::drivers {

struct MqttWill {
    std::string topic, payload;
    bool retain = true;
};

class MqttClient {
  public:
    struct Callbacks {
        // Connected (again): subscribe and publish what a fresh session needs here.
        std::function<void()> connected;
        // A broker that refused the box or a connection lost: why, once per change.
        std::function<void(const std::string& why)> trouble;
        std::function<void(const std::string& topic, const std::string& payload)> message;
    };
    // Starts connecting to host:port at once. Throws std::runtime_error when libmosquitto cannot
    // start (out of memory, no thread).
    MqttClient(const std::string& client_id, const std::string& host, int port, MqttWill will,
               Callbacks callbacks);
    MqttClient(const MqttClient&) = delete;
    MqttClient& operator=(const MqttClient&) = delete;
    // Publishes `closing` (the will's topic, retained) if connected, disconnects, joins.
    ~MqttClient();
    void set_closing_message(std::string payload) { closing_ = std::move(payload); }
    // Queued by the library; dropped when not connected (a fresh connection republishes what is
    // retained). QoS 1.
    void publish(const std::string& topic, const std::string& payload, bool retain);
    void subscribe(const std::string& topic);
    bool connected() const;

    struct State;

  private:
    std::unique_ptr<State> state_;
    std::string closing_;
};

}  // namespace calbox::drivers
