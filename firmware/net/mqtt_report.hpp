#pragma once
// The box on an MQTT broker, for Home Assistant (docs/network.md): its state and each cycle's
// result as JSON, its availability with a last will, and Home Assistant's discovery (retained,
// published again whenever Home Assistant says it is back online): sensors for the last measured
// error, the drift and when it was calibrated, a binary sensor "needs calibrating", and a button
// that starts a cycle through the console's `start`. Everything it does on the box runs on the
// loop's thread, posted there from the client's.
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "firmware/loop/event_loop.hpp"
#include "firmware/settings/settings_table.hpp"
#include "hal/log.hpp"
#include "hal/network.hpp"

namespace calbox::firmware {

// The MQTT broker the box reports to, Home Assistant's discovery with it: off while `broker` is
// empty. Topics: calbox/NODE/...; discovery: PREFIX/<component>/NODE/<object>/config.
struct MqttSettings {
    std::string broker;  // HOST:PORT
    std::string node_id = "calbox";
    std::string discovery_prefix = "homeassistant";
    // The login Home Assistant's Mosquitto add-on wants (hal::MqttBroker).
    std::string user;
    std::string password_file;
    bool tls = false;
    std::string ca_file;
    std::string protocol = "3.1.1";  // or "5"
    // Whether a message on calbox/NODE/command may start a cycle (and Home Assistant is offered
    // the start button): off, a box moves its machine only for a person at it or a page that
    // knows its password.
    bool remote_start = false;
};

// MQTT's table of the configuration: [mqtt].
SettingsTable<MqttSettings> mqtt_settings_table();

class MqttReport {
  public:
    struct Context {
        LoopInbox& inbox;
        // On the loop's thread:
        std::function<nlohmann::json()> status;  // BoxNews::status
        std::function<std::string(const std::string& line)> console;
        hal::Log log;
        std::string version;
        hal::Network& network;
    };
    // Starts connecting; a broker not there is one log line, and tried again with back-off.
    MqttReport(Context context, const MqttSettings& settings);
    MqttReport(const MqttReport&) = delete;
    MqttReport& operator=(const MqttReport&) = delete;
    ~MqttReport();  // "offline" on the availability topic, then disconnects

    // On the loop's thread: the status changed; a cycle ended (its history line).
    void publish_status(const nlohmann::json& status);
    void publish_result(const nlohmann::json& history_entry);

    std::string topic(const std::string& leaf) const {
        return "calbox/" + settings_.node_id + "/" + leaf;
    }
    // Home Assistant's discovery messages: (topic, retained JSON config); the start button's
    // config empty without remote start, which takes back one announced before.
    std::vector<std::pair<std::string, std::string>> discovery() const;

  private:
    // On the loop's thread: a fresh session, or Home Assistant back online (discovery again).
    void on_connected(bool fresh);
    // On the loop: Home Assistant's birth message, or a remote start where it is on.
    void on_message(const std::string& topic, const std::string& payload);
    Context c_;
    MqttSettings settings_;
    std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);  // posted jobs check it
    std::unique_ptr<hal::MqttSession> client_;
};

}  // namespace calbox::firmware
