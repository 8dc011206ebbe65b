#include "firmware/app/box_config.hpp"

#include <toml++/toml.h>

#include <functional>
#include <sstream>
#include <vector>

namespace calbox::firmware {
namespace {

using K = ConfigKind;

// One key of a part's table bound to that part's member of BoxSettings.
struct BoundKey {
    std::function<std::string(const BoxSettings&)> get;
    std::function<void(BoxSettings&, std::string_view)> set;
};

struct Schema {
    std::vector<ConfigEntry> entries;  // table by table, as the file is written
    std::vector<BoundKey> keys;        // entries[i]'s
    std::vector<std::function<void(const BoxSettings&)>> checks;
    std::string table_names;  // "cycle, setup, ..."
};

template <class Part>
void add(Schema& schema, Part BoxSettings::*part, const SettingsTable<Part>& table) {
    for (const auto& key : table.keys) {
        schema.entries.push_back(
            {std::string(table.name) + "." + std::string(key.info.name), key.info});
        schema.keys.push_back(
            {[part, get = key.get](const BoxSettings& s) { return get(s.*part); },
             [part, set = key.set, info = key.info](BoxSettings& s, std::string_view text) {
                 set(s.*part, info, text);
             }});
    }
    if (table.check != nullptr)
        schema.checks.emplace_back(
            [part, check = table.check](const BoxSettings& s) { check(s.*part); });
    if (!schema.table_names.empty()) schema.table_names += ", ";
    schema.table_names += table.name;
}

// The parts' tables in the order the file is written.
Schema make_schema() {
    Schema schema;
    for (const auto& table : cycle_settings_tables()) add(schema, &BoxSettings::cycle, table);
    add(schema, &BoxSettings::console, console_settings_table());
    add(schema, &BoxSettings::modbus, modbus_settings_table());
    add(schema, &BoxSettings::link, link_settings_table());
    add(schema, &BoxSettings::report, report_settings_table());
    add(schema, &BoxSettings::web, web_settings_table());
    add(schema, &BoxSettings::mqtt, mqtt_settings_table());
    return schema;
}

const Schema& schema() {
    static const Schema built = make_schema();
    return built;
}

std::string_view table_of(std::string_view name) {
    return name.substr(0, name.find('.'));
}
std::string_view key_of(std::string_view name) {
    return name.substr(name.find('.') + 1);
}

// Where `entry` (one of the schema's, as Configuration::find gives it) is bound.
const BoundKey& bound(const ConfigEntry& entry) {
    return schema().keys[static_cast<std::size_t>(&entry - schema().entries.data())];
}

// A TOML node as the key's text, or a ConfigError saying what the key takes.
std::string node_text(const toml::node& node, const KeyInfo& k) {
    // A choice of numbers (a baud rate) is written as a number too.
    if (const auto* v = node.as_integer();
        v && (k.kind == K::integer || k.kind == K::number || k.kind == K::choice))
        return std::to_string(v->get());
    if (const auto* d = node.as_floating_point(); d && k.kind == K::number)
        return setting_text::number(d->get());
    if (const auto* b = node.as_boolean(); b && k.kind == K::flag)
        return setting_text::flag_text(b->get());
    if (const auto* s = node.as_string(); s && (k.kind == K::text || k.kind == K::choice))
        return s->get();
    throw ConfigError("must be " + setting_text::range(k));
}

}  // namespace

BoxConfig BoxConfig::from_toml(const std::string& text, const std::string& file) {
    toml::table root;
    try {
        root = toml::parse(text, file);
    } catch (const toml::parse_error& e) {
        throw ConfigError(file + ":" + std::to_string(e.source().begin.line) + ": " +
                          std::string(e.description()));
    }
    BoxConfig config;
    const auto where = [&file](const toml::node& n) {
        return file + ":" + std::to_string(n.source().begin.line) + ": ";
    };
    for (const auto& [table_key, table_node] : root) {
        const std::string table(table_key.str());
        const toml::table* t = table_node.as_table();
        bool known_table = false;
        for (const auto& e : schema().entries)
            known_table = known_table || table_of(e.name) == table;
        if (t == nullptr || !known_table) {
            throw ConfigError(where(table_node) + "[" + table + "] is not a table calbox knows (" +
                              schema().table_names + ")");
        }
        for (const auto& [key, node] : *t) {
            const std::string prefix = where(node) + "[" + table + "] " + std::string(key.str());
            const ConfigEntry* entry = config.find(table + "." + std::string(key.str()));
            if (entry == nullptr) throw ConfigError(prefix + ": unknown key");
            try {
                bound(*entry).set(config.settings_, node_text(node, entry->info));
            } catch (const ConfigError& e) {
                throw ConfigError(prefix + ": " + e.what());
            }
        }
    }
    try {
        config.check_agreement();
    } catch (const ConfigError& e) {
        throw ConfigError(file + ": " + e.what());
    }
    return config;
}

std::string BoxConfig::to_toml() const {
    std::ostringstream out;
    out << "# calbox configuration (docs/appliance.md, Configuration). Written by the box: "
           "`config save`.\n";
    std::string_view table;
    const auto& entries = schema().entries;
    for (std::size_t i = 0; i < entries.size(); ++i) {
        const ConfigEntry& e = entries[i];
        if (table_of(e.name) != table) {
            table = table_of(e.name);
            out << "\n[" << table << "]\n";
        }
        out << key_of(e.name) << " = ";
        const std::string value = schema().keys[i].get(settings_);
        if (e.info.kind == K::text || e.info.kind == K::choice) {
            // A TOML basic string: quotes and backslashes escaped (a value is one line).
            out << '"';
            for (const char c : value) {
                if (c == '"' || c == '\\') out << '\\';
                out << c;
            }
            out << '"';
        } else {
            out << value;
        }
        out << "  # " << setting_text::range(e.info) << "\n";
    }
    return out.str();
}

std::span<const ConfigEntry> BoxConfig::entries() const {
    return schema().entries;
}

const ConfigEntry& BoxConfig::entry_or_throw(std::string_view key) const {
    const ConfigEntry* entry = find(key);
    if (entry == nullptr) {
        throw ConfigError("'" + std::string(key) +
                          "' is not a configuration key (config list shows them)");
    }
    return *entry;
}

std::string BoxConfig::get(std::string_view key) const {
    return bound(entry_or_throw(key)).get(settings_);
}

std::string BoxConfig::default_value(std::string_view key) const {
    return bound(entry_or_throw(key)).get(BoxSettings{});
}

void BoxConfig::set(std::string_view key, std::string_view value) {
    const BoundKey& k = bound(entry_or_throw(key));
    BoxConfig changed = *this;
    try {
        k.set(changed.settings_, value);
        changed.check_agreement();
    } catch (const ConfigError& e) {
        throw ConfigError(std::string(key) + ": " + e.what());
    }
    *this = std::move(changed);
}

void BoxConfig::reset(std::string_view key) {
    const BoundKey& k = bound(entry_or_throw(key));
    BoxConfig changed = *this;
    k.set(changed.settings_, default_value(key));
    changed.check_agreement();
    *this = std::move(changed);
}

void BoxConfig::check_agreement() const {
    for (const auto& check : schema().checks) check(settings_);
}

}  // namespace calbox::firmware
