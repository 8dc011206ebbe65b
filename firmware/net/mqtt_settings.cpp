// MQTT's table of the configuration: [mqtt], the broker, the box's name in its topics and Home
// Assistant's discovery prefix.
#include <string>

#include "firmware/net/mqtt_report.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;
using setting_text::choice;
using setting_text::flag;
using setting_text::flag_text;
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
    {{"user",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "log in to the broker as this user (Home Assistant's Mosquitto add-on: a Home Assistant "
      "user or one of its logins); empty: anonymous"},
     [](const MqttSettings& s) { return s.user; },
     [](MqttSettings& s, const KeyInfo&, std::string_view t) { s.user = one_line(t); }},
    {{"password_file",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "the user's password, alone on the first line of this file, which only its owner may read "
      "(chmod 600); the password itself is never shown or logged"},
     [](const MqttSettings& s) { return s.password_file; },
     [](MqttSettings& s, const KeyInfo&, std::string_view t) { s.password_file = one_line(t); }},
    {{"tls",
      K::flag,
      {},
      0,
      0,
      {},
      true,
      "speak TLS to the broker (its port is then usually 8883), checking its certificate and "
      "name"},
     [](const MqttSettings& s) { return flag_text(s.tls); },
     [](MqttSettings& s, const KeyInfo& k, std::string_view t) { s.tls = flag(k, t); }},
    {{"ca_file",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "the authority (PEM) that signed the broker's certificate; empty: the system's "
      "authorities"},
     [](const MqttSettings& s) { return s.ca_file; },
     [](MqttSettings& s, const KeyInfo&, std::string_view t) { s.ca_file = one_line(t); }},
    {{"protocol", K::choice, {}, 0, 0, "3.1.1|5", true, "the MQTT version to speak"},
     [](const MqttSettings& s) { return s.protocol; },
     [](MqttSettings& s, const KeyInfo& k, std::string_view t) { s.protocol = choice(k, t); }},
    {{"remote_start",
      K::flag,
      {},
      0,
      0,
      {},
      true,
      "let a message on calbox/NODE/command start a cycle (and offer Home Assistant its start "
      "button); off: MQTT only reports"},
     [](const MqttSettings& s) { return flag_text(s.remote_start); },
     [](MqttSettings& s, const KeyInfo& k, std::string_view t) { s.remote_start = flag(k, t); }},
};

// What single keys cannot say: a password needs a user, a CA file TLS.
void check_mqtt(const MqttSettings& s) {
    if (!s.password_file.empty() && s.user.empty())
        throw ConfigError("mqtt.password_file needs mqtt.user");
    if (!s.ca_file.empty() && !s.tls) throw ConfigError("mqtt.ca_file needs mqtt.tls = true");
}

}  // namespace

SettingsTable<MqttSettings> mqtt_settings_table() {
    return {"mqtt", kMqttKeys, check_mqtt};
}

}  // namespace calbox::firmware
