#pragma once
// A session with an MQTT broker that never blocks its caller: it connects in the background,
// reconnects whenever the broker is not there, goes or refuses it, and calls back on a network
// thread of its own.
#include <functional>
#include <string>

#include "core/net/endpoints.hpp"

namespace calbox::hal {

// Said for the client by the broker when it goes without a word; `goodbye` is said on the same
// topic by the client itself when the session ends (empty: nothing).
struct MqttWill {
    std::string topic, payload;
    bool retain = true;
    std::string goodbye;
};

// The broker and how the box logs in to it: Home Assistant's Mosquitto add-on wants a user and
// a password, often over TLS (port 8883).
struct MqttBroker {
    net::HostPort address;
    std::string user;           // empty: anonymous
    std::string password_file;  // the password alone in a file its owner only reads (mode 0600)
    bool tls = false;           // the broker's certificate checked, its name included
    std::string ca_file;        // the authority that signed it; empty: the system's authorities
    int protocol_version = 4;   // MQTT's protocol level: 4 is 3.1.1, 5 is 5
};

struct MqttCallbacks {
    // Connected (again): subscribe and publish what a fresh session needs here.
    std::function<void()> connected;
    // A broker that refused the box or a connection lost: why, once per change.
    std::function<void(const std::string& why)> trouble;
    std::function<void(const std::string& topic, const std::string& payload)> message;
};

// Destroyed: says the will's goodbye (retained) if connected, disconnects, joins its thread.
class MqttSession {
  public:
    virtual ~MqttSession() = default;
    // Queued; dropped when not connected (a fresh connection republishes what is retained).
    // QoS 1.
    virtual void publish(const std::string& topic, const std::string& payload, bool retain) = 0;
    virtual void subscribe(const std::string& topic) = 0;
    virtual bool connected() const = 0;
};

}  // namespace calbox::hal
