#include "board/sim/print_json.hpp"

#include <array>
#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace calbox::sim {
namespace {

constexpr const char* kSchema = "calbox.print/1";

nlohmann::json to_json(const Vec3& v) {
    return nlohmann::json::array({v.x, v.y, v.z});
}

Vec3 vec3_from(const nlohmann::json& j, const char* what) {
    if (!j.is_array() || j.size() != 3)
        throw std::runtime_error(std::string(what) + " must be [x, y, z]");
    Vec3 v{j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
        throw std::runtime_error(std::string(what) + " must be finite");
    }
    return v;
}

}  // namespace

std::string print_to_json(const PrintRecord& record) {
    nlohmann::json strokes = nlohmann::json::array();
    for (const auto& s : record.result.strokes) {
        strokes.push_back({{"commanded_a", to_json(s.commanded_a_mm)},
                           {"commanded_b", to_json(s.commanded_b_mm)},
                           {"a", to_json(s.a_mm)},
                           {"b", to_json(s.b_mm)},
                           {"width_mm", s.width_mm},
                           {"top_mm", {s.top_a_mm, s.top_b_mm}},
                           {"line", s.line}});
    }
    const nlohmann::json j{{"schema", kSchema},
                           {"scenario", record.scenario},
                           {"job", record.job},
                           {"machine_kind", record.machine_kind},
                           {"lines_run", record.result.lines_run},
                           {"replies", record.result.replies},
                           {"strokes", strokes}};
    return j.dump(1) + "\n";
}

PrintRecord print_from_json(const std::string& text) {
    PrintRecord r;
    try {
        const auto j = nlohmann::json::parse(text);
        if (!j.is_object() || j.value("schema", "") != kSchema) {
            throw std::runtime_error(std::string("not a print record (schema ") + kSchema + ")");
        }
        r.scenario = j.at("scenario").get<std::string>();
        r.job = j.at("job").get<std::string>();
        r.machine_kind = j.at("machine_kind").get<std::string>();
        r.result.lines_run = j.at("lines_run").get<int>();
        r.result.replies = j.at("replies").get<std::vector<std::string>>();
        for (const auto& s : j.at("strokes")) {
            Stroke stroke;
            stroke.commanded_a_mm = vec3_from(s.at("commanded_a"), "commanded_a");
            stroke.commanded_b_mm = vec3_from(s.at("commanded_b"), "commanded_b");
            stroke.a_mm = vec3_from(s.at("a"), "a");
            stroke.b_mm = vec3_from(s.at("b"), "b");
            stroke.width_mm = s.at("width_mm").get<double>();
            if (!(stroke.width_mm > 0 && stroke.width_mm < 100))
                throw std::runtime_error("width_mm out of range");
            const auto top = s.at("top_mm").get<std::array<double, 2>>();
            if (!(std::isfinite(top[0]) && std::isfinite(top[1]) && std::abs(top[0]) < 1e4 &&
                  std::abs(top[1]) < 1e4))
                throw std::runtime_error("top_mm out of range");
            stroke.top_a_mm = top[0];
            stroke.top_b_mm = top[1];
            stroke.line = s.at("line").get<int>();
            r.result.strokes.push_back(stroke);
        }
    } catch (const nlohmann::json::exception& e) {
        throw std::runtime_error(std::string("malformed print record: ") + e.what());
    }
    return r;
}

}  // namespace calbox::sim
