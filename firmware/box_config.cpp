#include "firmware/box_config.hpp"

#include <toml++/toml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "board/devices.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "core/models/register_words.hpp"
#include "core/number_text.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;

// The schema. Ranges are what the box can do sensibly, each with its reason where it is not
// plain: a long press under 0.5 s is an accidental one; more than 16 frames do not lower the
// noise further than the target's own texture.
constexpr ConfigKey kSchema[] = {
    {"cycle.frames_per_capture",
     K::integer,
     "1",
     "photos",
     1,
     16,
     {},
     false,
     "photos averaged per capture (more: less noise, longer capture)"},
    {"cycle.long_press_ms",
     K::integer,
     "1500",
     "ms",
     500,
     10000,
     {},
     false,
     "a press at least this long cancels (in review: cancels instead of applying)"},
    {"setup.calibration_views",
     K::integer,
     "12",
     "views",
     3,
     60,
     {},
     false,
     "board views asked for in the camera's set-up"},
    {"setup.calibration_pattern",
     K::text,
     "chessboard:11x8@20",
     {},
     0,
     0,
     {},
     false,
     "the board held in front of the camera (calbox camera --pattern's form)"},
    {"setup.plane_pattern",
     K::text,
     "chessboard:9x6@20",
     {},
     0,
     0,
     {},
     false,
     "the board laid on the bed for the plane"},
    {"setup.plane_board_thickness_mm",
     K::number,
     "0",
     "mm",
     0,
     20,
     {},
     false,
     "the plane board's thickness: the bed is this far below its surface"},
    {"setup.reference_marks",
     K::text,
     "DICT_APRILTAG_36h11",
     {},
     0,
     0,
     {},
     false,
     "the fixed reference marks' dictionary (OpenCV's name): at least 2 stuck outside the work "
     "area, seen with the plane and checked at each cycle's start; \"none\": no camera check"},
    {"setup.camera_moved_limit_mm",
     K::number,
     "0.05",
     "mm",
     0.005,
     5,
     {},
     false,
     "how far the reference marks may seem to move on the bed before a cycle stops (the camera "
     "has moved)"},
    {"records.keep_cycles",
     K::integer,
     "50",
     "cycles",
     1,
     100000,
     {},
     false,
     "cycle records kept in the data directory; older ones are pruned"},
    {"records.max_size_mb",
     K::integer,
     "500",
     "MB",
     1,
     1000000,
     {},
     false,
     "the records' total size; the oldest are pruned past it"},
    {"records.keep_photos",
     K::flag,
     "false",
     {},
     0,
     0,
     {},
     false,
     "keep each cycle's photos (PNG) in its record"},
    {"console.device",
     K::text,
     "stdin",
     {},
     0,
     0,
     {},
     true,
     "the console's device: a serial device's path, \"pty\" (a pseudo-terminal, its path "
     "logged and linked as DATA/console), \"stdin\" (standard input when it is a terminal), "
     "or empty for none"},
    {"console.baud", K::choice, "115200", "baud", 0, 0, "9600|19200|38400|57600|115200|230400",
     true, "the console UART's speed"},
    {"modbus.server",
     K::text,
     "",
     {},
     0,
     0,
     {},
     true,
     "serve the PLC map: tcp:HOST:PORT or rtu:DEVICE:BAUD; empty: no server"},
    {"modbus.client",
     K::text,
     "",
     {},
     0,
     0,
     {},
     true,
     "write each result into this controller's registers; empty: none"},
    {"modbus.client_map",
     K::text,
     "",
     {},
     0,
     0,
     {},
     true,
     "the client's map file (value_name = register); empty: the whole block from 0"},
    {"modbus.word_order",
     K::choice,
     "abcd",
     {},
     0,
     0,
     "abcd|cdab|badc|dcba",
     true,
     "the floats' word order on Modbus"},
    {"modbus.response_timeout_ms",
     K::integer,
     "1000",
     "ms",
     50,
     60000,
     {},
     true,
     "how long a Modbus reply may take"},
    {"modbus.byte_timeout_ms",
     K::integer,
     "500",
     "ms",
     5,
     10000,
     {},
     true,
     "the longest gap inside one Modbus reply"},
};

std::string_view table_of(std::string_view name) {
    return name.substr(0, name.find('.'));
}
std::string_view key_of(std::string_view name) {
    return name.substr(name.find('.') + 1);
}

std::string range_text(const ConfigKey& k) {
    if (k.kind == K::choice) return "one of " + std::string(k.choices);
    if (k.kind == K::flag) return "true or false";
    if (k.kind == K::text) return "text";
    const bool whole = k.kind == K::integer;
    // Appended, not `"literal" + std::string&&`: GCC 12 at -O2 warns falsely on the latter
    // (-Wrestrict, GCC bug 105329).
    std::string text = whole ? "a whole number " : "a number ";
    text += number_text("%.10g", k.min);
    text += " to ";
    text += number_text("%.10g", k.max);
    if (!k.unit.empty()) (text += ' ') += k.unit;
    return text;
}

bool is_choice(const ConfigKey& k, std::string_view word) {
    std::string_view rest = k.choices;
    while (!rest.empty()) {
        const auto bar = rest.find('|');
        if (rest.substr(0, bar) == word) return true;
        if (bar == std::string_view::npos) break;
        rest.remove_prefix(bar + 1);
    }
    return false;
}

// The console's text as the key's value; throws ConfigError "why" (without the key).
BoxConfig::Value parse_value(const ConfigKey& k, std::string_view text) {
    const auto out_of_range = [&] {
        return ConfigError("'" + std::string(text) + "' is not " + range_text(k));
    };
    switch (k.kind) {
        case K::integer: {
            std::int64_t v = 0;
            const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
            if (ec != std::errc() || end != text.data() + text.size() || v < k.min || v > k.max)
                throw out_of_range();
            return v;
        }
        case K::number: {
            // from_chars for double is in GCC 12's library.
            double v = 0;
            const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
            if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v) ||
                v < k.min || v > k.max)
                throw out_of_range();
            return v;
        }
        case K::flag:
            if (text == "true") return true;
            if (text == "false") return false;
            throw out_of_range();
        case K::choice:
            if (!is_choice(k, text)) throw out_of_range();
            return std::string(text);
        case K::text:
            if (text.find_first_of("\n\r") != std::string_view::npos)
                throw ConfigError("a value is one line");
            return std::string(text);
    }
    throw out_of_range();
}

// What a text key's value must be beyond text.
void check_text(std::string_view name, const std::string& value) {
    try {
        if (name == "setup.calibration_pattern" || name == "setup.plane_pattern")
            (void)geometry::parse_pattern_spec(value);
        if (name == "setup.reference_marks" && value != kNoReferenceMarks)
            (void)geometry::aruco_dictionary_id(value);
        if ((name == "modbus.server" || name == "modbus.client") && !value.empty())
            (void)board::parse_modbus_endpoint(value);
    } catch (const std::invalid_argument& e) {
        throw ConfigError(e.what());
    }
}

std::string value_text(const BoxConfig::Value& v) {
    if (const auto* i = std::get_if<std::int64_t>(&v)) return std::to_string(*i);
    if (const auto* d = std::get_if<double>(&v)) return number_text("%.10g", *d);
    if (const auto* b = std::get_if<bool>(&v)) return *b ? "true" : "false";
    return std::get<std::string>(v);
}

const ConfigKey& key_or_throw(std::string_view name) {
    const ConfigKey* k = find_config_key(name);
    if (k == nullptr) {
        throw ConfigError("'" + std::string(name) +
                          "' is not a configuration key (config list shows them)");
    }
    return *k;
}

}  // namespace

std::span<const ConfigKey> config_schema() {
    return kSchema;
}

const ConfigKey* find_config_key(std::string_view name) {
    for (const auto& k : kSchema)
        if (k.name == name) return &k;
    return nullptr;
}

BoxConfig::BoxConfig() {
    for (const auto& k : kSchema)
        values_.emplace(std::string(k.name), parse_value(k, k.default_value));
}

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
        for (const auto& k : kSchema) known_table = known_table || table_of(k.name) == table;
        if (t == nullptr || !known_table) {
            throw ConfigError(where(table_node) + "[" + table +
                              "] is not a table calbox knows (cycle, setup, records, console, "
                              "modbus)");
        }
        for (const auto& [key, node] : *t) {
            const std::string name = table + "." + std::string(key.str());
            const ConfigKey* k = find_config_key(name);
            const std::string prefix = where(node) + "[" + table + "] " + std::string(key.str());
            if (k == nullptr) throw ConfigError(prefix + ": unknown key");
            std::string as_text;
            // A choice of numbers (a baud rate) is written as a number too.
            if (const auto* v = node.as_integer();
                v && (k->kind == K::integer || k->kind == K::number || k->kind == K::choice))
                as_text = std::to_string(v->get());
            else if (const auto* d = node.as_floating_point(); d && k->kind == K::number)
                as_text = number_text("%.10g", d->get());
            else if (const auto* b = node.as_boolean(); b && k->kind == K::flag)
                as_text = b->get() ? "true" : "false";
            else if (const auto* s = node.as_string();
                     s && (k->kind == K::text || k->kind == K::choice))
                as_text = s->get();
            else
                throw ConfigError(prefix + ": must be " + range_text(*k));
            try {
                auto value = parse_value(*k, as_text);
                if (k->kind == K::text) check_text(k->name, std::get<std::string>(value));
                config.values_[name] = std::move(value);
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
    out << "# calbox configuration (README, Configuration). Written by the box: `config save`.\n";
    std::string_view table;
    for (const auto& k : kSchema) {
        if (table_of(k.name) != table) {
            table = table_of(k.name);
            out << "\n[" << table << "]\n";
        }
        const auto& v = values_.at(std::string(k.name));
        out << key_of(k.name) << " = ";
        if (std::holds_alternative<std::string>(v)) {
            // A TOML basic string: quotes and backslashes escaped (a value is one line).
            out << '"';
            for (const char c : std::get<std::string>(v)) {
                if (c == '"' || c == '\\') out << '\\';
                out << c;
            }
            out << '"';
        } else {
            out << value_text(v);
        }
        out << "  # " << range_text(k) << "\n";
    }
    return out.str();
}

std::string BoxConfig::get(std::string_view key) const {
    key_or_throw(key);
    return value_text(values_.find(key)->second);
}

void BoxConfig::set(std::string_view key, std::string_view value) {
    const ConfigKey& k = key_or_throw(key);
    BoxConfig changed = *this;
    try {
        auto v = parse_value(k, value);
        if (k.kind == K::text) check_text(k.name, std::get<std::string>(v));
        changed.values_.find(key)->second = std::move(v);
        changed.check_agreement();
    } catch (const ConfigError& e) {
        throw ConfigError(std::string(key) + ": " + e.what());
    }
    *this = std::move(changed);
}

void BoxConfig::reset(std::string_view key) {
    const ConfigKey& k = key_or_throw(key);
    BoxConfig changed = *this;
    changed.values_.find(key)->second = parse_value(k, k.default_value);
    changed.check_agreement();
    *this = std::move(changed);
}

void BoxConfig::check_agreement() const {
    if (!text("modbus.client_map").empty() && text("modbus.client").empty())
        throw ConfigError("[modbus] client_map: needs client");
}

std::int64_t BoxConfig::integer(std::string_view key) const {
    return std::get<std::int64_t>(values_.find(key)->second);
}
double BoxConfig::number(std::string_view key) const {
    return std::get<double>(values_.find(key)->second);
}
const std::string& BoxConfig::text(std::string_view key) const {
    return std::get<std::string>(values_.find(key)->second);
}
bool BoxConfig::flag(std::string_view key) const {
    return std::get<bool>(values_.find(key)->second);
}

ModbusConfig BoxConfig::modbus() const {
    ModbusConfig m;
    m.server = text("modbus.server");
    m.client = text("modbus.client");
    m.client_map = text("modbus.client_map");
    m.word_order = text("modbus.word_order");
    m.response_timeout_ms = static_cast<std::uint32_t>(integer("modbus.response_timeout_ms"));
    m.byte_timeout_ms = static_cast<std::uint32_t>(integer("modbus.byte_timeout_ms"));
    return m;
}

CycleSettings BoxConfig::cycle_settings(CycleSettings base) const {
    base.frames_per_capture = static_cast<int>(integer("cycle.frames_per_capture"));
    base.long_press = std::chrono::milliseconds(integer("cycle.long_press_ms"));
    base.calibration_views = static_cast<int>(integer("setup.calibration_views"));
    base.calibration_pattern = text("setup.calibration_pattern");
    base.plane_pattern = text("setup.plane_pattern");
    base.plane_board_thickness_mm = number("setup.plane_board_thickness_mm");
    base.reference_marks = text("setup.reference_marks");
    base.camera_moved_limit_mm = number("setup.camera_moved_limit_mm");
    base.records.keep_cycles = static_cast<int>(integer("records.keep_cycles"));
    base.records.max_bytes = static_cast<std::uintmax_t>(integer("records.max_size_mb")) * 1000000U;
    base.records.keep_photos = flag("records.keep_photos");
    return base;
}

}  // namespace calbox::firmware
