// The planar mode's files: measurements.json and result.json, written and read in one place.
#include <algorithm>
#include <cmath>

#include "core/modes/json_file.hpp"
#include "core/modes/mark_records.hpp"
#include "core/modes/planar.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {

using geometry::Point2;

namespace {

using nlohmann::json;

constexpr const char* kPlanarMeasurementsSchema = "calbox.planar-measurements/1";
constexpr const char* kPlanarResultSchema = "calbox.planar-result/1";

json frame_json(const std::optional<PlanarFrame>& f) {
    if (!f) return nullptr;
    return {{"work_zero_mm", point_json(f->work_zero_mm)},
            {"work_zero_from", f->work_zero_from},
            {"travel_mm",
             {f->travel_min_x_mm, f->travel_min_y_mm, f->travel_max_x_mm, f->travel_max_y_mm}},
            {"firmware", f->firmware},
            {"kind", f->kind}};
}

PlanarFrame frame_from(const json& j, const std::string& source) {
    PlanarFrame f;
    f.work_zero_mm = point_from(j.at("work_zero_mm"));
    f.work_zero_from = j.at("work_zero_from").get<std::string>();
    const auto travel = j.at("travel_mm").get<std::vector<double>>();
    if (travel.size() != 4 || !(travel[2] > travel[0] && travel[3] > travel[1]))
        throw RecordError(source + ": frame.travel_mm is [min x, min y, max x, max y]");
    f.travel_min_x_mm = travel[0], f.travel_min_y_mm = travel[1];
    f.travel_max_x_mm = travel[2], f.travel_max_y_mm = travel[3];
    f.firmware = j.at("firmware").get<std::string>();
    f.kind = j.at("kind").get<std::string>();
    if (!std::isfinite(f.work_zero_mm.x) || !std::isfinite(f.work_zero_mm.y))
        throw RecordError(source + ": frame.work_zero_mm is not finite");
    return f;
}

}  // namespace

std::string planar_measurements_to_json(const PlanarMeasurement& m) {
    json holes = json::array();
    for (const auto& h : m.holes)
        holes.push_back(mark_json(h, &PlanarHoleMeasurement::commanded_mm, "commanded_mm"));
    json backlash = nullptr;
    if (m.backlash_hole)
        backlash = {{"column", m.backlash_hole->index.column},
                    {"row", m.backlash_hole->index.row},
                    {"commanded_mm", point_json(m.backlash_hole->commanded_mm)},
                    {"measured_mm", point_json(m.backlash_hole->measured_mm)},
                    {"sigma_mm", m.backlash_hole->sigma_mm}};
    const json j{{"schema", kPlanarMeasurementsSchema},
                 {"machine_fingerprint", m.machine_fingerprint},
                 {"target_fingerprint", m.target_fingerprint},
                 {"photos", m.photos},
                 {"columns", m.columns},
                 {"rows", m.rows},
                 {"pitch_mm", m.pitch_mm},
                 {"mirrored", m.mirrored},
                 {"holes", holes},
                 {"backlash_hole", backlash},
                 {"missing", nodes_json(m.missing)},
                 {"extra_mm", points_json(m.extra_mm)}};
    return j.dump(1) + "\n";
}

PlanarMeasurement planar_measurements_from_json(const std::string& text,
                                                const std::string& source) {
    const json j = parse_record(text, source, kPlanarMeasurementsSchema, "planar measurements");
    try {
        PlanarMeasurement m;
        m.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        m.target_fingerprint = j.at("target_fingerprint").get<std::string>();
        m.photos = j.at("photos").get<std::vector<std::string>>();
        m.columns = j.at("columns").get<int>();
        m.rows = j.at("rows").get<int>();
        m.pitch_mm = j.at("pitch_mm").get<double>();
        m.mirrored = j.at("mirrored").get<bool>();
        if (m.columns < 7 || m.rows < 7 || !(m.pitch_mm > 0))
            throw RecordError(source + ": the grid must be at least 7 x 7 at a positive pitch");
        for (const auto& h : j.at("holes"))
            m.holes.push_back(mark_from(h, &PlanarHoleMeasurement::commanded_mm, "commanded_mm",
                                        m.columns, m.rows, source, "hole"));
        if (const auto& b = j.at("backlash_hole"); !b.is_null()) {
            PlanarHoleMeasurement h;
            h.index = {b.at("column").get<int>(), b.at("row").get<int>()};
            h.commanded_mm = point_from(b.at("commanded_mm"));
            h.measured_mm = point_from(b.at("measured_mm"));
            h.sigma_mm = b.at("sigma_mm").get<double>();
            m.backlash_hole = h;
        }
        m.missing = nodes_from(j.at("missing"));
        m.extra_mm = points_from(j.at("extra_mm"));
        return m;
    } catch (const json::exception& e) {
        throw RecordError(source + ": " + e.what());
    }
}

std::string planar_result_to_json(const PlanarSolution& s, const FirmwareSettings& firmware) {
    const auto& names = models::planar_parameters();
    json parameters = json::array();
    for (std::size_t j = 0; j < names.size(); ++j) {
        json p{{"name", names[j].name},
               {"unit", names[j].unit},
               {"seed_symbol", names[j].seed_symbol},
               {"value", s.fit.parameters[j]},
               {"uncertainty", s.fit.uncertainty[j]},
               {"fitted", s.fit.fitted[j]}};
        for (const auto& h : s.fit.held)
            if (h.parameter == static_cast<int>(j)) p["absorbed_by"] = h.absorbed_by;
        parameters.push_back(p);
    }
    json holes = json::array();
    for (std::size_t i = 0; i < s.commanded_mm.size(); ++i)
        holes.push_back({{"commanded_mm", point_json(s.commanded_mm[i])},
                         {"error_mm", point_json(s.error_mm[i])},
                         {"residual_mm", point_json(s.fit.residuals_mm[i])}});
    const json j{{"schema", kPlanarResultSchema},
                 {"machine_fingerprint", s.machine_fingerprint},
                 {"tool_length_mm", s.tool_length_mm},
                 {"parameters", parameters},
                 {"placement",
                  {{"rotation_rad", s.fit.rotation_rad},
                   {"translation_mm", point_json(s.fit.translation_mm)},
                   {"bed_mirrored", s.bed_mirrored ? json(*s.bed_mirrored) : json(nullptr)}}},
                 {"rigid_part_left_out",
                  {{"rotation_rad", s.rigid_part.rotation_rad},
                   {"offset_mm", point_json(s.rigid_part.offset_mm)}}},
                 {"rank", s.fit.rank},
                 {"condition", s.fit.condition},
                 {"residual_rms_mm", s.fit.residual_rms_mm},
                 {"unit_variance_ratio", s.fit.unit_variance_ratio},
                 {"measurement_sigma_mm", s.measurement_sigma_mm},
                 {"before", statistics_json(s.before)},
                 {"after", statistics_json(s.after)},
                 {"valid_area_mm", {s.min_x_mm, s.min_y_mm, s.max_x_mm, s.max_y_mm}},
                 {"frame", frame_json(s.frame)},
                 {"backlash_mm", s.backlash_mm ? point_json(*s.backlash_mm) : json(nullptr)},
                 {"firmware",
                  {{"lines", firmware.lines},
                   {"mean_left_mm", firmware.mean_left_mm},
                   {"mean_before_mm", firmware.mean_before_mm}}},
                 {"holes", holes}};
    return j.dump(1) + "\n";
}

PlanarSolution planar_result_from_json(const std::string& text, const std::string& source) {
    const json j = parse_record(text, source, kPlanarResultSchema, "planar result");
    try {
        PlanarSolution s;
        s.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        s.tool_length_mm = j.at("tool_length_mm").get<double>();
        const auto& names = models::planar_parameters();
        const json& parameters = j.at("parameters");
        if (!parameters.is_array() || parameters.size() != names.size())
            throw RecordError(source + ": parameters must list the model's " +
                              std::to_string(names.size()));
        for (std::size_t k = 0; k < names.size(); ++k) {
            const json& p = parameters[k];
            if (p.at("name").get<std::string>() != names[k].name)
                throw RecordError(source + ": parameter " + std::to_string(k) + " must be " +
                                  names[k].name);
            s.fit.parameters[k] = p.at("value").get<double>();
            s.fit.uncertainty[k] = p.at("uncertainty").get<double>();
            s.fit.fitted[k] = p.at("fitted").get<bool>();
            if (!std::isfinite(s.fit.parameters[k]))
                throw RecordError(source + ": parameter " + names[k].name + " is not finite");
        }
        s.fit.rotation_rad = j.at("placement").at("rotation_rad").get<double>();
        s.fit.translation_mm = point_from(j.at("placement").at("translation_mm"));
        if (const auto& placement = j.at("placement");
            placement.contains("bed_mirrored") && !placement.at("bed_mirrored").is_null())
            s.bed_mirrored = placement.at("bed_mirrored").get<bool>();
        s.rigid_part.rotation_rad = j.at("rigid_part_left_out").at("rotation_rad").get<double>();
        s.rigid_part.offset_mm = point_from(j.at("rigid_part_left_out").at("offset_mm"));
        s.fit.rank = j.at("rank").get<int>();
        s.fit.condition = j.at("condition").get<double>();
        s.fit.residual_rms_mm = j.at("residual_rms_mm").get<double>();
        s.fit.unit_variance_ratio = j.at("unit_variance_ratio").get<double>();
        s.measurement_sigma_mm = j.at("measurement_sigma_mm").get<double>();
        s.before = norm_statistics_from(j.at("before"));
        s.after = norm_statistics_from(j.at("after"));
        const auto area = j.at("valid_area_mm").get<std::vector<double>>();
        if (area.size() != 4 || !(area[2] > area[0] && area[3] > area[1]))
            throw RecordError(source + ": valid_area_mm is [min x, min y, max x, max y]");
        s.min_x_mm = area[0], s.min_y_mm = area[1], s.max_x_mm = area[2], s.max_y_mm = area[3];
        if (const auto& b = j.at("backlash_mm"); !b.is_null()) s.backlash_mm = point_from(b);
        if (j.contains("frame") && !j.at("frame").is_null())
            s.frame = frame_from(j.at("frame"), source);
        for (const auto& h : j.at("holes")) {
            s.commanded_mm.push_back(point_from(h.at("commanded_mm")));
            s.error_mm.push_back(point_from(h.at("error_mm")));
            s.fit.residuals_mm.push_back(point_from(h.at("residual_mm")));
        }
        return s;
    } catch (const json::exception& e) {
        throw RecordError(source + ": " + e.what());
    }
}

}  // namespace calbox::modes
