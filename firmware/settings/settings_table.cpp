#include "firmware/settings/settings_table.hpp"

#include <charconv>
#include <cmath>

#include "core/net/endpoints.hpp"
#include "core/number_text.hpp"

namespace calbox::firmware {
namespace setting_text {
namespace {

ConfigError out_of_range(const KeyInfo& k, std::string_view text) {
    return ConfigError("'" + std::string(text) + "' is not " + range(k));
}

}  // namespace

std::string range(const KeyInfo& k) {
    if (k.kind == ConfigKind::choice) return "one of " + std::string(k.choices);
    if (k.kind == ConfigKind::flag) return "true or false";
    if (k.kind == ConfigKind::text) return "text";
    const bool whole_number = k.kind == ConfigKind::integer;
    // Appended, not `"literal" + std::string&&`: GCC 12 at -O2 warns falsely on the latter
    // (-Wrestrict, GCC bug 105329).
    std::string text = whole_number ? "a whole number " : "a number ";
    text += number(k.min);
    text += " to ";
    text += number(k.max);
    if (!k.unit.empty()) (text += ' ') += k.unit;
    return text;
}

std::int64_t whole(const KeyInfo& k, std::string_view text) {
    std::int64_t v = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (ec != std::errc() || end != text.data() + text.size() || v < k.min || v > k.max)
        throw out_of_range(k, text);
    return v;
}

double decimal(const KeyInfo& k, std::string_view text) {
    // from_chars for double is in GCC 12's library.
    double v = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v) || v < k.min ||
        v > k.max)
        throw out_of_range(k, text);
    return v;
}

bool flag(const KeyInfo& k, std::string_view text) {
    if (text == "true") return true;
    if (text == "false") return false;
    throw out_of_range(k, text);
}

std::string choice(const KeyInfo& k, std::string_view text) {
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

std::string host_port(std::string_view text, bool names) {
    std::string value = one_line(text);
    if (value.empty()) return value;
    try {
        (void)net::parse_host_port(value, names);
    } catch (const std::invalid_argument& e) {
        throw ConfigError(e.what());
    }
    return value;
}

std::string number(double value) {
    return number_text("%.10g", value);
}

}  // namespace setting_text

const ConfigEntry* Configuration::find(std::string_view key) const {
    for (const auto& e : entries())
        if (e.name == key) return &e;
    return nullptr;
}

}  // namespace calbox::firmware
