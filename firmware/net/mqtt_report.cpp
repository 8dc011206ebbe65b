#include "firmware/net/mqtt_report.hpp"

#include <stdexcept>

namespace calbox::firmware {
namespace {

using json = nlohmann::json;

// The state topic's payload: what Home Assistant's templates read, flat.
json state_payload(const json& status) {
    json out = {{"state", status.at("state")},
                {"waiting", status.at("waiting")},
                {"cycle", status.at("cycle")},
                {"drift_mm", status.at("drift_mm")},
                {"last_calibrated", status.at("last_calibrated")},
                {"needs_calibration", status.at("needs_calibration")}};
    const auto headline = [](const json& f) -> json {
        if (f.is_null()) return nullptr;
        return f.at("mean_mm").is_null() ? f.at("rms_mm") : f.at("mean_mm");
    };
    const json& last = status.at("last");
    out["last_error_mm"] = last.is_null() ? json(nullptr) : headline(last.at("before"));
    out["last_after_mm"] = last.is_null() ? json(nullptr) : headline(last.at("after"));
    return out;
}

}  // namespace

MqttReport::MqttReport(Context context, const MqttSettings& settings)
    : c_(std::move(context)), settings_(settings) {
    hal::MqttBroker broker;
    broker.address = net::parse_host_port(settings_.broker, true);
    broker.user = settings_.user;
    broker.password_file = settings_.password_file;
    broker.tls = settings_.tls;
    broker.ca_file = settings_.ca_file;
    broker.protocol_version = settings_.protocol == "5" ? 5 : 4;
    const std::weak_ptr<bool> alive = alive_;
    LoopInbox& inbox = c_.inbox;
    // Each callback runs on the client's thread: it only posts to the loop.
    hal::MqttCallbacks callbacks;
    callbacks.connected = [this, alive, &inbox] {
        inbox.post([this, alive] {
            if (alive.lock()) on_connected(true);
        });
    };
    callbacks.trouble = [this, alive, &inbox](const std::string& why) {
        inbox.post([this, alive, why] {
            if (alive.lock()) c_.log.warning("mqtt: " + why);
        });
    };
    callbacks.message = [this, alive, &inbox](const std::string& topic,
                                              const std::string& payload) {
        inbox.post([this, alive, topic, payload] {
            if (alive.lock()) on_message(topic, payload);
        });
    };
    client_ = c_.network.mqtt("calbox-" + settings_.node_id, broker,
                              hal::MqttWill{topic("availability"), "offline", true, "offline"},
                              std::move(callbacks));
    c_.log("mqtt: reporting to " + settings_.broker + " as " + topic("") +
           (settings_.user.empty() ? "" : ", logged in as " + settings_.user) +
           (settings_.tls ? ", over TLS" : "") +
           (settings_.remote_start ? "; " + topic("command") + " starts a cycle"
                                   : "; remote start off"));
}

void MqttReport::on_message(const std::string& topic, const std::string& payload) {
    if (topic == settings_.discovery_prefix + "/status") {
        if (payload == "online") on_connected(false);
        return;
    }
    if (topic != this->topic("command") || !settings_.remote_start) return;
    if (payload != "start") {
        c_.log.warning("mqtt: command '" + payload.substr(0, 40) + "' is not one the box takes");
        return;
    }
    const json reply = json::parse(c_.console("start --json"));
    const bool started = reply.value("ok", false);
    c_.log.write(started ? hal::LogLevel::info : hal::LogLevel::warning,
                 "mqtt: start: " + (started ? std::string("started")
                                            : reply.value("error", std::string("refused"))));
}

MqttReport::~MqttReport() {
    alive_.reset();
    client_.reset();
}

std::vector<std::pair<std::string, std::string>> MqttReport::discovery() const {
    const std::string node = settings_.node_id;
    const json device = {{"identifiers", json::array({"calbox_" + node})},
                         {"name", "calbox " + node},
                         {"manufacturer", "calbox"},
                         {"model", "calbox camera box"},
                         {"sw_version", c_.version}};
    const auto config = [&](const std::string& component, const std::string& object, json fields) {
        fields["unique_id"] = "calbox_" + node + "_" + object;
        fields["object_id"] = "calbox_" + node + "_" + object;
        fields["availability_topic"] = topic("availability");
        fields["device"] = device;
        return std::pair{
            settings_.discovery_prefix + "/" + component + "/" + node + "/" + object + "/config",
            fields.dump()};
    };
    std::vector<std::pair<std::string, std::string>> configs = {
        config("sensor", "last_error",
               {{"name", "Last measured error"},
                {"state_topic", topic("state")},
                {"value_template", "{{ value_json.last_error_mm }}"},
                {"unit_of_measurement", "mm"},
                {"state_class", "measurement"},
                {"icon", "mdi:ruler"}}),
        config("sensor", "drift",
               {{"name", "Drift since calibration"},
                {"state_topic", topic("state")},
                {"value_template", "{{ value_json.drift_mm }}"},
                {"unit_of_measurement", "mm"},
                {"state_class", "measurement"}}),
        config("sensor", "last_calibrated",
               {{"name", "Last calibrated"},
                {"state_topic", topic("state")},
                {"value_template", "{{ value_json.last_calibrated }}"},
                {"device_class", "timestamp"}}),
        config("sensor", "state",
               {{"name", "State"},
                {"state_topic", topic("state")},
                {"value_template", "{{ value_json.state }}"}}),
        config("binary_sensor", "needs_calibrating",
               {{"name", "Needs calibrating"},
                {"state_topic", topic("state")},
                {"value_template", "{{ 'ON' if value_json.needs_calibration else 'OFF' }}"},
                {"device_class", "problem"}}),
        config("button", "start",
               {{"name", "Start calibration"},
                {"command_topic", topic("command")},
                {"payload_press", "start"}}),
    };
    // Without remote start Home Assistant is offered no button, and one a former configuration
    // announced is taken back: an empty retained config removes it.
    if (!settings_.remote_start) configs.back().second.clear();
    return configs;
}

void MqttReport::on_connected(bool fresh) {
    if (settings_.remote_start) client_->subscribe(topic("command"));
    client_->subscribe(settings_.discovery_prefix + "/status");
    for (const auto& [t, payload] : discovery()) client_->publish(t, payload, true);
    client_->publish(topic("availability"), "online", true);
    publish_status(c_.status());
    if (fresh) c_.log("mqtt: connected to " + settings_.broker);
}

void MqttReport::publish_status(const nlohmann::json& status) {
    client_->publish(topic("state"), state_payload(status).dump(), true);
}

void MqttReport::publish_result(const nlohmann::json& history_entry) {
    client_->publish(topic("result"), history_entry.dump(), true);
}

}  // namespace calbox::firmware
