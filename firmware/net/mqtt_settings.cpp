// MQTT's table of the configuration: [mqtt], the broker, the box's name in its topics and Home
// Assistant's discovery prefix.
#include <string>

#include "firmware/net/mqtt_report.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;
using setting_text::host_port;
using setting_text::one_line;

// One MQTT topic level of our own: no wildcards, no separators, nothing a broker would read
// otherwise.
std::string topic_word(std::string_view text) {
    std::string value = one_line(text);
    if (value.empty() || value.size() > 64 ||
        value.find_first_not_of(
            "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") !=
            std::string::npos)
        throw ConfigError("'" + value + "': 1 to 64 letters, digits, _ or -");
    return value;
}

const SettingKey<MqttSettings> kMqttKeys[] = {
    {{"broker",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "report to the MQTT broker at HOST:PORT (Home Assistant's discovery included); empty: no "
      "MQTT"},
     [](const MqttSettings& s) { return s.broker; },
     [](MqttSettings& s, const KeyInfo&, std::string_view t) { s.broker = host_port(t, true); }},
    {{"node_id",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "this box's name in its topics (calbox/NODE/...) and in Home Assistant's ids: letters, "
      "digits, _ and -"},
     [](const MqttSettings& s) { return s.node_id; },
     [](MqttSettings& s, const KeyInfo&, std::string_view t) { s.node_id = topic_word(t); }},
    {{"discovery_prefix",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "Home Assistant's discovery prefix (its MQTT integration's setting)"},
     [](const MqttSettings& s) { return s.discovery_prefix; },
     [](MqttSettings& s, const KeyInfo&, std::string_view t) {
         s.discovery_prefix = topic_word(t);
     }},
};

}  // namespace

SettingsTable<MqttSettings> mqtt_settings_table() {
    return {"mqtt", kMqttKeys};
}

}  // namespace calbox::firmware
