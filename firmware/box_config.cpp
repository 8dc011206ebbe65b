#include "firmware/box_config.hpp"

#include <stdexcept>

#include "core/models/register_words.hpp"
#include "core/models/toml_reader.hpp"
#include "drivers/modbus_link.hpp"

namespace calbox::firmware {

BoxConfig read_box_config(const std::string& text, const std::string& file) {
    const toml::table root = models::parse_toml(text, file);
    models::TomlReader top(file, root, "");
    top.finish();  // only tables at the top
    for (const auto& [key, node] : root) {
        if (key.str() != "modbus") {
            throw models::MachineFileError(file + ": [" + std::string(key.str()) +
                                           "] is not a table calbox knows (modbus)");
        }
    }
    BoxConfig config;
    if (const toml::table* t = models::subtable(file, root, "modbus")) {
        models::TomlReader r(file, *t, "modbus");
        ModbusConfig& m = config.modbus;
        r.text("server", m.server, {});
        r.text("client", m.client, {});
        r.text("client_map", m.client_map, {});
        r.text("word_order", m.word_order, {"abcd", "cdab", "badc", "dcba"});
        int response = static_cast<int>(m.response_timeout_ms);
        int byte = static_cast<int>(m.byte_timeout_ms);
        r.integer("response_timeout_ms", response, 50, 60000);
        r.integer("byte_timeout_ms", byte, 5, 10000);
        m.response_timeout_ms = static_cast<std::uint32_t>(response);
        m.byte_timeout_ms = static_cast<std::uint32_t>(byte);
        r.finish();
        for (const auto* endpoint : {&m.server, &m.client}) {
            if (endpoint->empty()) continue;
            try {
                (void)drivers::parse_modbus_endpoint(*endpoint);
            } catch (const std::invalid_argument& e) {
                r.fail(endpoint == &m.server ? "server" : "client", e.what());
            }
        }
        if (!m.client_map.empty() && m.client.empty()) r.fail("client_map", "needs client");
    }
    return config;
}

}  // namespace calbox::firmware
