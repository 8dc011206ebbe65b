#pragma once
// The modes' JSON files are read through this one gate: malformed text, or a file of another
// schema, is a RecordError naming the file. Include only from .cpp files (nlohmann's header).
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "core/modes/record_error.hpp"

namespace calbox::modes {

inline nlohmann::json parse_record(std::string_view text, const std::string& source,
                                   const char* schema, const char* what) {
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
        throw RecordError(source + ": malformed " + what + ": " + e.what());
    }
    if (!j.is_object() || !j.contains("schema") || !j["schema"].is_string() ||
        j["schema"].get<std::string>() != schema) {
        throw RecordError(source + ": not a " + what + " file (schema " + schema + ")");
    }
    return j;
}

}  // namespace calbox::modes
