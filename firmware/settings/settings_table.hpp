#pragma once
// A part's settings table: each key described once (its kind, unit, range and help) and bound to
// the member of the part's own settings that it sets, so that the configuration file, the
// console's `config` rows and the web page all read the same declaration. The readers below turn
// a key's text into its value or say why not (ConfigError, without the key's name: the caller
// adds where).
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace calbox::firmware {

class ConfigError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

enum class ConfigKind { integer, number, text, choice, flag };

// What a key is, as the file, the console and the page describe it.
struct KeyInfo {
    std::string_view name;  // within its table: "frames_per_capture"
    ConfigKind kind = ConfigKind::text;
    std::string_view unit;       // empty when the value has none
    double min = 0, max = 0;     // integer and number
    std::string_view choices;    // choice: the allowed words, "|" between them
    bool needs_restart = false;  // read when the box starts, not at each cycle
    std::string_view doc;
};

// One key bound to the member of `Settings` it sets: its value as the console writes it, and the
// console's text parsed, checked and stored (throws ConfigError saying why).
template <class Settings>
struct SettingKey {
    KeyInfo info;
    std::string (*get)(const Settings& settings);
    void (*set)(Settings& settings, const KeyInfo& key, std::string_view text);
};

// One [table] of the file and the part's settings it fills. `check` says what single keys cannot
// (a Modbus map needs a client): it throws ConfigError naming the keys.
template <class Settings>
struct SettingsTable {
    std::string_view name;  // "web"
    std::span<const SettingKey<Settings>> keys;
    void (*check)(const Settings& settings) = nullptr;
};

// The readers of a key's text, for every table.
namespace setting_text {

// What the key takes, as an error or the file's comment says it: "a whole number 1 to 16 photos".
std::string range(const KeyInfo& key);
std::int64_t whole(const KeyInfo& key, std::string_view text);
double decimal(const KeyInfo& key, std::string_view text);
bool flag(const KeyInfo& key, std::string_view text);
std::string choice(const KeyInfo& key, std::string_view text);
std::string one_line(std::string_view text);
// HOST:PORT as the web server (an IP address) or the MQTT client (names too) takes it, or empty.
std::string host_port(std::string_view text, bool names);
// A number as the console and the file write it.
std::string number(double value);
inline std::string flag_text(bool value) {
    return value ? "true" : "false";
}

}  // namespace setting_text

// One key of the box's configuration: "table.key" and what it is.
struct ConfigEntry {
    std::string name;
    KeyInfo info;
};

// The box's configuration as the console and the page change it, one key at a time: every change
// validated before it takes (on a ConfigError nothing changed), an unknown key a ConfigError.
class Configuration {
  public:
    virtual ~Configuration() = default;
    virtual std::span<const ConfigEntry> entries() const = 0;  // table by table, as in the file
    virtual std::string get(std::string_view key) const = 0;
    virtual std::string default_value(std::string_view key) const = 0;
    virtual void set(std::string_view key, std::string_view value) = 0;
    virtual void reset(std::string_view key) = 0;
    virtual void reset_all() = 0;  // every key at its default
    // Every key, table by table, each with its unit and range in a comment.
    virtual std::string to_toml() const = 0;
    // Null when the key is unknown.
    const ConfigEntry* find(std::string_view key) const;
};

}  // namespace calbox::firmware
