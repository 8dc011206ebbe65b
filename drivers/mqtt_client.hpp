#pragma once
// An MQTT client over libmosquitto, on a network thread of its own: it connects in the background
// with a last will, reconnects with back-off (1 s doubling to 60 s) whenever the broker is not
// there, goes or refuses it, and never blocks its caller. Callbacks run on that thread.
#include <functional>
#include <memory>
#include <string>

namespace calbox::drivers {

// Said for the client by the broker when it goes without a word; `goodbye` is said on the same
// topic by the client itself when it is destroyed (empty: nothing).
struct MqttWill {
    std::string topic, payload;
    bool retain = true;
    std::string goodbye;
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
    // Says the will's goodbye (retained) if connected, disconnects, joins.
    ~MqttClient();
    // Queued by the library; dropped when not connected (a fresh connection republishes what is
    // retained). QoS 1.
    void publish(const std::string& topic, const std::string& payload, bool retain);
    void subscribe(const std::string& topic);
    bool connected() const;

    struct State;

  private:
    std::unique_ptr<State> state_;
};

}  // namespace calbox::drivers
