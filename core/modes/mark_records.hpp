#pragma once
// The grid-mark modes' records (galvo's and planar's measurements and results) share their
// marks' shape and their error figures: written and read here once. Include only from .cpp
// files (nlohmann's header).
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/models/galvo_field.hpp"
#include "core/models/planar_errors.hpp"
#include "core/modes/json_file.hpp"
#include "core/targets/galvo_target.hpp"

namespace calbox::modes {

// A mark found on the grid: its node, its kind, where the machine was told to put it (under
// `nominal_key`: "intended_mm" in a scanner's field, "commanded_mm" in machine coordinates),
// where it was measured and how well.
template <class Mark>
nlohmann::json mark_json(const Mark& m, geometry::Point2 Mark::*nominal, const char* nominal_key) {
    return {{"column", m.index.column},
            {"row", m.index.row},
            {"large", m.large},
            {nominal_key, point_json(m.*nominal)},
            {"measured_mm", point_json(m.measured_mm)},
            {"sigma_mm", m.sigma_mm}};
}

// Throws RecordError for a mark off the `columns` x `rows` grid ("a node lies outside the 31 x
// 31 grid"), nlohmann's errors for a missing or mistyped field.
template <class Mark>
Mark mark_from(const nlohmann::json& j, geometry::Point2 Mark::*nominal, const char* nominal_key,
               int columns, int rows, const std::string& source, const char* mark_name) {
    Mark m;
    m.index = {j.at("column").get<int>(), j.at("row").get<int>()};
    if (m.index.column < 0 || m.index.row < 0 || m.index.column >= columns || m.index.row >= rows)
        throw RecordError(source + ": a " + mark_name + " lies outside the " +
                          std::to_string(columns) + " x " + std::to_string(rows) + " grid");
    m.large = j.at("large").get<bool>();
    m.*nominal = point_from(j.at(nominal_key));
    m.measured_mm = point_from(j.at("measured_mm"));
    m.sigma_mm = j.at("sigma_mm").get<double>();
    return m;
}

// The grid's nodes where no mark was found, as [column, row] pairs.
inline nlohmann::json nodes_json(const std::vector<targets::GridIndex>& nodes) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& i : nodes) out.push_back({i.column, i.row});
    return out;
}
inline std::vector<targets::GridIndex> nodes_from(const nlohmann::json& j) {
    std::vector<targets::GridIndex> out;
    for (const auto& i : j) out.push_back({i.at(0).get<int>(), i.at(1).get<int>()});
    return out;
}

// A list of points, [[x, y], ...]: the marks seen off the grid (spatter, a chip, a second
// burn), a galvo table's commands, where the marks were meant and landed.
inline nlohmann::json points_json(const std::vector<geometry::Point2>& points_mm) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& p : points_mm) out.push_back(point_json(p));
    return out;
}
inline std::vector<geometry::Point2> points_from(const nlohmann::json& j) {
    std::vector<geometry::Point2> out;
    for (const auto& p : j) out.push_back(point_from(p));
    return out;
}

// The galvo's error figures (mean, RMS, worst) and the planar mode's (the five-number summary).
inline nlohmann::json statistics_json(const models::ErrorStatistics& s) {
    return {
        {"mean_mm", s.mean_mm}, {"rms_mm", s.rms_mm}, {"max_mm", s.max_mm}, {"points", s.points}};
}
inline models::ErrorStatistics error_statistics_from(const nlohmann::json& j) {
    return {j.at("mean_mm").get<double>(), j.at("rms_mm").get<double>(),
            j.at("max_mm").get<double>(), j.at("points").get<std::size_t>()};
}
inline nlohmann::json statistics_json(const models::NormStatistics& s) {
    return {{"max_mm", s.max_mm}, {"q3_mm", s.q3_mm},   {"median_mm", s.median_mm},
            {"q1_mm", s.q1_mm},   {"min_mm", s.min_mm}, {"mean_mm", s.mean_mm},
            {"std_mm", s.std_mm}, {"points", s.points}};
}
inline models::NormStatistics norm_statistics_from(const nlohmann::json& j) {
    models::NormStatistics s;
    s.max_mm = j.at("max_mm").get<double>();
    s.q3_mm = j.at("q3_mm").get<double>();
    s.median_mm = j.at("median_mm").get<double>();
    s.q1_mm = j.at("q1_mm").get<double>();
    s.min_mm = j.at("min_mm").get<double>();
    s.mean_mm = j.at("mean_mm").get<double>();
    s.std_mm = j.at("std_mm").get<double>();
    s.points = j.at("points").get<std::size_t>();
    return s;
}

}  // namespace calbox::modes
