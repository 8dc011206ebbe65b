#pragma once
// The modes' JSON files are read through this one gate: malformed text, or a file of another
// schema, is a RecordError naming the file. Include only from .cpp files (nlohmann's header).
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "core/geometry/types.hpp"
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

// A point in the modes' files: [x, y].
inline nlohmann::json point_json(geometry::Point2 p) {
    return nlohmann::json::array({p.x, p.y});
}
// Throws nlohmann's type_error for anything but a pair of numbers; readers turn it into a
// RecordError naming the file.
inline geometry::Point2 point_from(const nlohmann::json& j) {
    if (!j.is_array() || j.size() != 2)
        throw nlohmann::json::type_error::create(302, "a point is [x, y]", &j);
    return {j.at(0).get<double>(), j.at(1).get<double>()};
}

}  // namespace calbox::modes
