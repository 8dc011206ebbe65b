#pragma once
// The box's configuration, put together from its parts' own tables (the cycle's [cycle], [setup]
// and [records], the console's, Modbus's, the machine link's, the report's, the web page's and
// MQTT's): typed settings (BoxSettings, whose members hold the defaults), read strictly from TOML
// (an unknown key or a wrong value names the key and the line), changed one key at a time by the
// console (validated before it takes), and written back whole. Options given on the command line
// win over the file.
#include <span>
#include <string>
#include <string_view>

#include "firmware/console/console.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/links/make_link.hpp"
#include "firmware/net/box_news.hpp"
#include "firmware/net/mqtt_report.hpp"
#include "firmware/net/web_window.hpp"
#include "firmware/plc/plc_link.hpp"
#include "firmware/settings/settings_table.hpp"

namespace calbox::firmware {

// Everything the configuration sets, each part's own; a default-constructed one is the defaults.
struct BoxSettings {
    CycleSettings cycle;
    ConsoleSettings console;
    ModbusSettings modbus;
    LinkSettings link;
    ReportSettings report;
    WebSettings web;
    MqttSettings mqtt;
};

class BoxConfig final : public Configuration {
  public:
    BoxConfig() = default;  // every key at its default

    // Strict: a wrong type, a value out of range, an unknown table or key is a ConfigError
    // "FILE:LINE: [table] key: why". Keys not in the file keep their defaults.
    static BoxConfig from_toml(const std::string& text, const std::string& file);
    std::string to_toml() const override;

    std::span<const ConfigEntry> entries() const override;
    std::string get(std::string_view key) const override;
    std::string default_value(std::string_view key) const override;
    void set(std::string_view key, std::string_view value) override;
    void reset(std::string_view key) override;
    void reset_all() override { settings_ = BoxSettings{}; }
    bool operator==(const BoxConfig& other) const { return to_toml() == other.to_toml(); }

    const BoxSettings& settings() const { return settings_; }

  private:
    const ConfigEntry& entry_or_throw(std::string_view key) const;  // ConfigError when unknown
    void check_agreement() const;  // each table's own check (a Modbus map needs its client)
    BoxSettings settings_;
};

}  // namespace calbox::firmware
