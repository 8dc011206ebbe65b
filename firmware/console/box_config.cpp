#include "firmware/console/box_config.hpp"

#include <toml++/toml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/geometry/pattern_spec.hpp"
#include "core/net/endpoints.hpp"
#include "core/net/http_text.hpp"
#include "core/number_text.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;

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

ConfigError out_of_range(const ConfigKey& k, std::string_view text) {
    return ConfigError("'" + std::string(text) + "' is not " + range_text(k));
}

std::int64_t whole(const ConfigKey& k, std::string_view text) {
    std::int64_t v = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (ec != std::errc() || end != text.data() + text.size() || v < k.min || v > k.max)
        throw out_of_range(k, text);
    return v;
}

double decimal(const ConfigKey& k, std::string_view text) {
    // from_chars for double is in GCC 12's library.
    double v = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v) || v < k.min ||
        v > k.max)
        throw out_of_range(k, text);
    return v;
}

bool flag(const ConfigKey& k, std::string_view text) {
    if (text == "true") return true;
    if (text == "false") return false;
    throw out_of_range(k, text);
}

std::string choice(const ConfigKey& k, std::string_view text) {
    std::string_view rest = k.choices;
    while (!rest.empty()) {
        const auto bar = rest.find('|');
        if (rest.substr(0, bar) == text) return std::string(text);
        if (bar == std::string_view::npos) break;
        rest.remove_prefix(bar + 1);
    }
    throw out_of_range(k, text);
}

std::string one_line(std::string_view text) {
    if (text.find_first_of("\n\r") != std::string_view::npos)
        throw ConfigError("a value is one line");
    return std::string(text);
}

std::string pattern(std::string_view text) {
    try {
        (void)geometry::parse_pattern_spec(one_line(text));
    } catch (const std::invalid_argument& e) {
        throw ConfigError(e.what());
    }
    return std::string(text);
}

std::optional<net::ModbusEndpoint> endpoint(std::string_view text) {
    if (one_line(text).empty()) return std::nullopt;
    try {
        return net::parse_modbus_endpoint(std::string(text));
    } catch (const std::invalid_argument& e) {
        throw ConfigError(e.what());
    }
}

// HOST:PORT as the web server or the MQTT client takes it, or empty (off).
std::string host_port(std::string_view text, bool names) {
    const std::string value = one_line(text);
    if (value.empty()) return value;
    try {
        (void)net::parse_host_port(value, names);
    } catch (const std::invalid_argument& e) {
        throw ConfigError(e.what());
    }
    return value;
}

// One MQTT topic level of our own: no wildcards, no separators, nothing a broker would read
// otherwise.
std::string topic_word(std::string_view text) {
    const std::string value = one_line(text);
    if (value.empty() || value.size() > 64 ||
        value.find_first_not_of(
            "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") !=
            std::string::npos)
        throw ConfigError("'" + value + "': 1 to 64 letters, digits, _ or -");
    return value;
}

std::string text_of(const std::optional<net::ModbusEndpoint>& e) {
    return e ? endpoint_text(*e) : std::string();
}

std::string decimal_text(double v) {
    return number_text("%.10g", v);
}

}  // namespace

models::MachineLinkSettings LinkSettings::over(const models::MachineFile& machine) const {
    models::MachineFile m = machine;
    if (kind != "machine") m.link.kind = kind;
    if (!url.empty()) m.link.url = url;
    if (!key_file.empty()) m.link.key_file = key_file;
    if (!ca_file.empty()) m.link.ca_file = ca_file;
    if (const auto why = models::link_mismatch(m); !why.empty())
        throw ConfigError("link.kind: " + why);
    return m.link;
}

namespace {

// The schema, table by table in the order the file is written. Ranges are what the box can do
// sensibly, each with its reason where it is not plain: a long press under 0.5 s is an accidental
// one; more than 16 frames do not lower the noise further than the target's own texture.
const ConfigKey kSchema[] = {
    {"cycle.frames_per_capture",
     K::integer,
     "photos",
     1,
     16,
     {},
     false,
     "photos averaged per capture (more: less noise, longer capture)",
     [](const BoxSettings& s) { return std::to_string(s.cycle.frames_per_capture); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.cycle.frames_per_capture = static_cast<int>(whole(k, t));
     }},
    {"cycle.long_press_ms",
     K::integer,
     "ms",
     500,
     10000,
     {},
     false,
     "a press at least this long cancels (in review: cancels instead of applying)",
     [](const BoxSettings& s) { return std::to_string(s.cycle.long_press.count()); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.cycle.long_press = std::chrono::milliseconds(whole(k, t));
     }},
    {"setup.calibration_views",
     K::integer,
     "views",
     3,
     60,
     {},
     false,
     "board views asked for in the camera's set-up",
     [](const BoxSettings& s) { return std::to_string(s.cycle.calibration_views); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.cycle.calibration_views = static_cast<int>(whole(k, t));
     }},
    {"setup.calibration_pattern",
     K::text,
     {},
     0,
     0,
     {},
     false,
     "the board held in front of the camera (calbox camera --pattern's form)",
     [](const BoxSettings& s) { return s.cycle.calibration_pattern; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         s.cycle.calibration_pattern = pattern(t);
     }},
    {"setup.plane_pattern",
     K::text,
     {},
     0,
     0,
     {},
     false,
     "the board laid on the bed for the plane",
     [](const BoxSettings& s) { return s.cycle.plane_pattern; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         s.cycle.plane_pattern = pattern(t);
     }},
    {"setup.plane_board_thickness_mm",
     K::number,
     "mm",
     0,
     20,
     {},
     false,
     "the plane board's thickness: the bed is this far below its surface",
     [](const BoxSettings& s) { return decimal_text(s.cycle.plane_board_thickness_mm); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.cycle.plane_board_thickness_mm = decimal(k, t);
     }},
    {"setup.reference_marks",
     K::text,
     {},
     0,
     0,
     {},
     false,
     "the fixed reference marks' dictionary (OpenCV's name): at least 2 stuck outside the work "
     "area, seen with the plane and checked at each cycle's start; \"none\": no camera check",
     [](const BoxSettings& s) { return s.cycle.reference_marks; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         const std::string marks = one_line(t);
         try {
             if (marks != kNoReferenceMarks) (void)geometry::aruco_dictionary_id(marks);
         } catch (const std::invalid_argument& e) {
             throw ConfigError(e.what());
         }
         s.cycle.reference_marks = marks;
     }},
    {"setup.camera_moved_limit_mm",
     K::number,
     "mm",
     0.005,
     5,
     {},
     false,
     "how far the reference marks may seem to move on the bed before a cycle stops (the camera "
     "has moved)",
     [](const BoxSettings& s) { return decimal_text(s.cycle.camera_moved_limit_mm); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.cycle.camera_moved_limit_mm = decimal(k, t);
     }},
    {"records.keep_cycles",
     K::integer,
     "cycles",
     1,
     100000,
     {},
     false,
     "cycle records kept in the data directory; older ones are pruned",
     [](const BoxSettings& s) { return std::to_string(s.cycle.records.keep_cycles); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.cycle.records.keep_cycles = static_cast<int>(whole(k, t));
     }},
    {"records.max_size_mb",
     K::integer,
     "MB",
     1,
     1000000,
     {},
     false,
     "the records' total size; the oldest are pruned past it",
     [](const BoxSettings& s) { return std::to_string(s.cycle.records.max_bytes / 1000000U); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.cycle.records.max_bytes = static_cast<std::uintmax_t>(whole(k, t)) * 1000000U;
     }},
    {"records.keep_photos",
     K::flag,
     {},
     0,
     0,
     {},
     false,
     "keep each cycle's photos (PNG) in its record",
     [](const BoxSettings& s) {
         return std::string(s.cycle.records.keep_photos ? "true" : "false");
     },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.cycle.records.keep_photos = flag(k, t);
     }},
    {"console.device",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "the console's device: a serial device's path, \"pty\" (a pseudo-terminal, its path "
     "logged and linked as DATA/console), \"stdin\" (standard input when it is a terminal), "
     "or empty for none",
     [](const BoxSettings& s) { return s.console.device; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) { s.console.device = one_line(t); }},
    {"console.baud", K::choice, "baud", 0, 0, "9600|19200|38400|57600|115200|230400", true,
     "the console UART's speed",
     [](const BoxSettings& s) { return std::to_string(s.console.baud); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.console.baud = std::stoi(choice(k, t));
     }},
    {"modbus.server",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "serve the PLC map: tcp:HOST:PORT or rtu:DEVICE:BAUD; empty: no server",
     [](const BoxSettings& s) { return text_of(s.modbus.server); },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) { s.modbus.server = endpoint(t); }},
    {"modbus.client",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "write each result into this controller's registers; empty: none",
     [](const BoxSettings& s) { return text_of(s.modbus.client); },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) { s.modbus.client = endpoint(t); }},
    {"modbus.client_map",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "the client's map file (value_name = register); empty: the whole block from 0",
     [](const BoxSettings& s) { return s.modbus.client_map; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         s.modbus.client_map = one_line(t);
     }},
    {"modbus.word_order",
     K::choice,
     {},
     0,
     0,
     "abcd|cdab|badc|dcba",
     true,
     "the floats' word order on Modbus",
     [](const BoxSettings& s) { return std::string(models::word_order_name(s.modbus.word_order)); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.modbus.word_order = models::parse_word_order(choice(k, t));
     }},
    {"modbus.response_timeout_ms",
     K::integer,
     "ms",
     50,
     60000,
     {},
     true,
     "how long a Modbus reply may take",
     [](const BoxSettings& s) { return std::to_string(s.modbus.timeouts.response_ms); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.modbus.timeouts.response_ms = static_cast<std::uint32_t>(whole(k, t));
     }},
    {"modbus.byte_timeout_ms",
     K::integer,
     "ms",
     5,
     10000,
     {},
     true,
     "the longest gap inside one Modbus reply",
     [](const BoxSettings& s) { return std::to_string(s.modbus.timeouts.byte_ms); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.modbus.timeouts.byte_ms = static_cast<std::uint32_t>(whole(k, t));
     }},
    {"link.kind",
     K::choice,
     {},
     0,
     0,
     "machine|serial|moonraker|octoprint|duet",
     true,
     "how the box reaches the machine: machine (its machine file's [link]), its serial port, or "
     "a host that owns the printer (docs/links.md)",
     [](const BoxSettings& s) { return s.link.kind; },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) { s.link.kind = choice(k, t); }},
    {"link.url",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "the host's address, http://HOST:PORT or https://... (empty: the machine file's)",
     [](const BoxSettings& s) { return s.link.url; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         const std::string url = one_line(t);
         if (!url.empty()) {
             try {
                 (void)net::parse_url(url);
             } catch (const std::invalid_argument& e) {
                 throw ConfigError(e.what());
             }
         }
         s.link.url = url;
     }},
    {"link.key_file",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "the file holding the host's API key, alone (empty: the machine file's)",
     [](const BoxSettings& s) { return s.link.key_file; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) { s.link.key_file = one_line(t); }},
    {"link.ca_file",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "an https host's certificate authority, a PEM file (empty: the machine file's, else the "
     "system's)",
     [](const BoxSettings& s) { return s.link.ca_file; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) { s.link.ca_file = one_line(t); }},
    {"report.needs_calibration_mm",
     K::number,
     "mm",
     0.001,
     10,
     {},
     false,
     "a cycle's error as jobs met it (its mean, a delta's RMS; through the correction the box "
     "keeps, for a galvo or a router) past this: the machine needs calibrating (the page, MQTT, "
     "/metrics)",
     [](const BoxSettings& s) { return decimal_text(s.needs_calibration_mm); },
     [](BoxSettings& s, const ConfigKey& k, std::string_view t) {
         s.needs_calibration_mm = decimal(k, t);
     }},
    {"web.listen",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "serve the box's web page at HOST:PORT (an IP address; 0.0.0.0 for every interface); "
     "empty: no web page",
     [](const BoxSettings& s) { return s.web.listen; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         s.web.listen = host_port(t, false);
     }},
    {"web.password",
     K::text,
     {},
     0,
     0,
     {},
     false,
     "the web page's password, as its hash (the console's `web password` sets it); empty: the "
     "page changes nothing",
     [](const BoxSettings& s) { return s.web.password_hash; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         const std::string hash = one_line(t);
         if (!hash.empty() && !net::is_password_hash(hash))
             throw ConfigError("not a password hash: set the password with `web password`");
         s.web.password_hash = hash;
     }},
    {"mqtt.broker",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "report to the MQTT broker at HOST:PORT (Home Assistant's discovery included); empty: no "
     "MQTT",
     [](const BoxSettings& s) { return s.mqtt.broker; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         s.mqtt.broker = host_port(t, true);
     }},
    {"mqtt.node_id",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "this box's name in its topics (calbox/NODE/...) and in Home Assistant's ids: letters, "
     "digits, _ and -",
     [](const BoxSettings& s) { return s.mqtt.node_id; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) { s.mqtt.node_id = topic_word(t); }},
    {"mqtt.discovery_prefix",
     K::text,
     {},
     0,
     0,
     {},
     true,
     "Home Assistant's discovery prefix (its MQTT integration's setting)",
     [](const BoxSettings& s) { return s.mqtt.discovery_prefix; },
     [](BoxSettings& s, const ConfigKey&, std::string_view t) {
         s.mqtt.discovery_prefix = topic_word(t);
     }},
};

std::string_view table_of(std::string_view name) {
    return name.substr(0, name.find('.'));
}
std::string_view key_of(std::string_view name) {
    return name.substr(name.find('.') + 1);
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

std::string endpoint_text(const net::ModbusEndpoint& e) {
    if (e.kind == net::ModbusEndpoint::Kind::tcp)
        return "tcp:" + e.host + ":" + std::to_string(e.port);
    return "rtu:" + e.device + ":" + std::to_string(e.baud);
}

std::span<const ConfigKey> config_schema() {
    return kSchema;
}

const ConfigKey* find_config_key(std::string_view name) {
    for (const auto& k : kSchema)
        if (k.name == name) return &k;
    return nullptr;
}

std::string default_text(const ConfigKey& key) {
    return key.get(BoxSettings{});
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
                              "modbus, link, report, web, mqtt)");
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
                k->set(config.settings_, *k, as_text);
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
    for (const auto& k : kSchema) {
        if (table_of(k.name) != table) {
            table = table_of(k.name);
            out << "\n[" << table << "]\n";
        }
        out << key_of(k.name) << " = ";
        const std::string value = k.get(settings_);
        if (k.kind == K::text || k.kind == K::choice) {
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
        out << "  # " << range_text(k) << "\n";
    }
    return out.str();
}

std::string BoxConfig::get(std::string_view key) const {
    return key_or_throw(key).get(settings_);
}

void BoxConfig::set(std::string_view key, std::string_view value) {
    const ConfigKey& k = key_or_throw(key);
    BoxConfig changed = *this;
    try {
        k.set(changed.settings_, k, value);
        changed.check_agreement();
    } catch (const ConfigError& e) {
        throw ConfigError(std::string(key) + ": " + e.what());
    }
    *this = std::move(changed);
}

void BoxConfig::reset(std::string_view key) {
    const ConfigKey& k = key_or_throw(key);
    BoxConfig changed = *this;
    k.set(changed.settings_, k, default_text(k));
    changed.check_agreement();
    *this = std::move(changed);
}

void BoxConfig::check_agreement() const {
    if (!settings_.modbus.client_map.empty() && !settings_.modbus.client)
        throw ConfigError("[modbus] client_map: needs client");
}

}  // namespace calbox::firmware
