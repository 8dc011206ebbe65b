#pragma once
// The box's configuration: typed settings (BoxSettings, whose members hold the defaults) and one
// schema binding each key to its member, with its unit, range and what it does. Read strictly
// from TOML (an unknown key or a wrong value names the key and the line), changed one key at a
// time by the console (validated before it takes), and written back whole. Options given on the
// command line win over the file.
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

#include "core/models/register_words.hpp"
#include "core/net/endpoints.hpp"
#include "firmware/cycle/cycle.hpp"
#include "hal/register_link.hpp"

namespace calbox::firmware {

class ConfigError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct ConsoleSettings {
    std::string device = "stdin";  // a serial device's path, "pty", "stdin" or "" for none
    int baud = 115200;
};

struct ModbusSettings {
    std::optional<net::ModbusEndpoint> server;  // serve the PLC map
    std::optional<net::ModbusEndpoint> client;  // the controller the results are written to
    std::string client_map;  // a map file (value_name = register); empty: the whole block from 0
    models::WordOrder word_order = models::WordOrder::abcd;
    hal::ModbusTimeouts timeouts;
};

// The machine's link as the configuration sets it over the machine file's [link]: each value
// left at its default keeps the machine file's.
struct LinkSettings {
    std::string kind =
        "machine";         // machine (the machine file's) | serial | moonraker | octoprint | duet
    std::string url;       // a host's
    std::string key_file;  // the host's API key, alone in the file
    std::string ca_file;   // an https host's certificate authority (PEM)
    // `machine`'s [link] with these over it; throws ConfigError when they do not fit its firmware.
    models::MachineLinkSettings over(const models::MachineFile& machine) const;
};

// The box's own web page (docs/network.md): off while `listen` is empty. Anything that changes
// state needs the password, kept only as its hash (hal/password.hpp).
struct WebSettings {
    std::string listen;  // HOST:PORT, an IP address to bind
    std::string password_hash;
};

// The MQTT broker the box reports to, Home Assistant's discovery with it: off while `broker` is
// empty. Topics: calbox/NODE/...; discovery: PREFIX/<component>/NODE/<object>/config.
struct MqttSettings {
    std::string broker;  // HOST:PORT
    std::string node_id = "calbox";
    std::string discovery_prefix = "homeassistant";
};

// Everything the configuration sets, typed; a default-constructed one is the defaults.
struct BoxSettings {
    CycleSettings cycle;
    ConsoleSettings console;
    ModbusSettings modbus;
    LinkSettings link;
    WebSettings web;
    MqttSettings mqtt;
    // A cycle's error as jobs met it (CycleReport::in_force) past this: the machine needs
    // calibrating (MQTT, the page, /metrics).
    double needs_calibration_mm = 0.05;
};

// "tcp:HOST:PORT" or "rtu:DEVICE:BAUD", as it is written.
std::string endpoint_text(const net::ModbusEndpoint& endpoint);

enum class ConfigKind { integer, number, text, choice, flag };

struct ConfigKey {
    std::string_view name;  // "table.key", as in the file
    ConfigKind kind;
    std::string_view unit;       // empty when the value has none
    double min = 0, max = 0;     // integer and number
    std::string_view choices;    // choice: the allowed words, "|" between them
    bool needs_restart = false;  // read when the box starts, not at each cycle
    std::string_view doc;
    // The member bound: its value as the console writes it, and the console's text parsed,
    // checked and stored (throws ConfigError saying why, without the key).
    std::string (*get)(const BoxSettings& settings);
    void (*set)(BoxSettings& settings, const ConfigKey& key, std::string_view text);
};

std::span<const ConfigKey> config_schema();
const ConfigKey* find_config_key(std::string_view name);  // nullptr when unknown
std::string default_text(const ConfigKey& key);           // the value in BoxSettings{}

class BoxConfig {
  public:
    BoxConfig() = default;  // every key at its default

    // Strict: a wrong type, a value out of range, an unknown table or key is a ConfigError
    // "FILE:LINE: [table] key: why". Keys not in the file keep their defaults.
    static BoxConfig from_toml(const std::string& text, const std::string& file);
    // Every key, table by table, each with its unit and range in a comment.
    std::string to_toml() const;

    // The value as the console shows it; ConfigError for an unknown key.
    std::string get(std::string_view key) const;
    // Validates (type, range, and what the value must agree with) before it takes; on a
    // ConfigError nothing changed.
    void set(std::string_view key, std::string_view value);
    void reset(std::string_view key);
    bool operator==(const BoxConfig& other) const { return to_toml() == other.to_toml(); }

    const BoxSettings& settings() const { return settings_; }

  private:
    void check_agreement() const;  // what single keys cannot say: modbus client_map needs client
    BoxSettings settings_;
};

}  // namespace calbox::firmware
