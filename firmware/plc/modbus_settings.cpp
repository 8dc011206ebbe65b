// Modbus's table of the configuration: [modbus], the PLC map the box serves and the controller it
// writes each result to.
#include <string>

#include "firmware/plc/plc_link.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;
using setting_text::choice;
using setting_text::one_line;
using setting_text::whole;

std::optional<net::ModbusEndpoint> endpoint(std::string_view text) {
    if (one_line(text).empty()) return std::nullopt;
    try {
        return net::parse_modbus_endpoint(std::string(text));
    } catch (const std::invalid_argument& e) {
        throw ConfigError(e.what());
    }
}

// As it is written; empty for none.
std::string text_of(const std::optional<net::ModbusEndpoint>& e) {
    return e ? e->text() : std::string();
}

const SettingKey<ModbusSettings> kModbusKeys[] = {
    {{"server",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "serve the PLC map: tcp:HOST:PORT or rtu:DEVICE:BAUD; empty: no server"},
     [](const ModbusSettings& s) { return text_of(s.server); },
     [](ModbusSettings& s, const KeyInfo&, std::string_view t) { s.server = endpoint(t); }},
    {{"client",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "write each result into this controller's registers; empty: none"},
     [](const ModbusSettings& s) { return text_of(s.client); },
     [](ModbusSettings& s, const KeyInfo&, std::string_view t) { s.client = endpoint(t); }},
    {{"client_map",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "the client's map file (value_name = register); empty: the whole block from 0"},
     [](const ModbusSettings& s) { return s.client_map; },
     [](ModbusSettings& s, const KeyInfo&, std::string_view t) { s.client_map = one_line(t); }},
    {{"word_order",
      K::choice,
      {},
      0,
      0,
      "abcd|cdab|badc|dcba",
      true,
      "the floats' word order on Modbus"},
     [](const ModbusSettings& s) { return std::string(models::word_order_name(s.word_order)); },
     [](ModbusSettings& s, const KeyInfo& k, std::string_view t) {
         s.word_order = models::parse_word_order(choice(k, t));
     }},
    {{"response_timeout_ms",
      K::integer,
      "ms",
      50,
      60000,
      {},
      true,
      "how long a Modbus reply may take"},
     [](const ModbusSettings& s) { return std::to_string(s.timeouts.response_ms); },
     [](ModbusSettings& s, const KeyInfo& k, std::string_view t) {
         s.timeouts.response_ms = static_cast<std::uint32_t>(whole(k, t));
     }},
    {{"byte_timeout_ms",
      K::integer,
      "ms",
      5,
      10000,
      {},
      true,
      "the longest gap inside one Modbus reply"},
     [](const ModbusSettings& s) { return std::to_string(s.timeouts.byte_ms); },
     [](ModbusSettings& s, const KeyInfo& k, std::string_view t) {
         s.timeouts.byte_ms = static_cast<std::uint32_t>(whole(k, t));
     }},
};

}  // namespace

SettingsTable<ModbusSettings> modbus_settings_table() {
    return {"modbus", kModbusKeys, [](const ModbusSettings& s) {
                if (!s.client_map.empty() && !s.client)
                    throw ConfigError("[modbus] client_map: needs client");
            }};
}

}  // namespace calbox::firmware
