#pragma once
// The box's configuration: one schema (every key with its type, default, unit, range and what it
// does), read strictly from TOML (an unknown key or a wrong value names the key and the line),
// changed one key at a time by the console (validated before it takes), and written back whole.
// Options given on the command line win over the file.
#include <cstdint>
#include <map>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>

#include "firmware/cycle.hpp"

namespace calbox::firmware {

class ConfigError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

enum class ConfigKind { integer, number, text, choice, flag };

struct ConfigKey {
    std::string_view name;  // "table.key", as in the file
    ConfigKind kind;
    std::string_view default_value;  // as written on the console
    std::string_view unit;           // empty when the value has none
    double min = 0, max = 0;         // integer and number
    std::string_view choices;        // choice: the allowed words, "|" between them
    bool needs_restart = false;      // read when the box starts, not at each cycle
    std::string_view doc;
};

std::span<const ConfigKey> config_schema();
const ConfigKey* find_config_key(std::string_view name);  // nullptr when unknown

struct ModbusConfig {
    std::string server;      // "tcp:HOST:PORT" or "rtu:DEVICE:BAUD"; empty: no server
    std::string client;      // the controller the results are written to; empty: none
    std::string client_map;  // a map file (value_name = register); empty: the whole block from 0
    std::string word_order = "abcd";
    std::uint32_t response_timeout_ms = 1000;
    std::uint32_t byte_timeout_ms = 500;
};

class BoxConfig {
  public:
    using Value = std::variant<std::int64_t, double, std::string, bool>;
    BoxConfig();  // every key at its default

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
    bool operator==(const BoxConfig&) const = default;

    std::int64_t integer(std::string_view key) const;
    double number(std::string_view key) const;
    const std::string& text(std::string_view key) const;
    bool flag(std::string_view key) const;

    ModbusConfig modbus() const;
    // The cycle's settings the configuration owns (frames, long press, set-up boards, records).
    CycleSettings cycle_settings(CycleSettings base) const;

  private:
    void check_agreement() const;  // what single keys cannot say: modbus client_map needs client
    std::map<std::string, Value, std::less<>> values_;
};

}  // namespace calbox::firmware
