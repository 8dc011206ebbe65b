#include "core/modes/delta_records.hpp"

#include <cmath>
#include <sstream>

#include "core/modes/json_file.hpp"

namespace calbox::modes {
namespace {

using nlohmann::json;

constexpr const char* kMeasurementsSchema = "calbox.measurements/1";
constexpr const char* kResultSchema = "calbox.delta-result/1";

// NaN is written as null; reading it back gives NaN, which the fit refuses with its reason.
double number(const json& v) {
    if (v.is_null()) return std::nan("");
    return v.get<double>();
}

json geometry_json(const models::DeltaGeometry& g) {
    return {{"diagonal_rod_mm", g.diagonal_rod_mm},
            {"diagonal_rod_trim_mm", g.diagonal_rod_trim_mm},
            {"radius_mm", g.radius_mm},
            {"tower_angle_trim_deg", g.tower_angle_trim_deg},
            {"endstop_offset_mm", g.endstop_offset_mm},
            {"height_mm", g.height_mm}};
}

models::DeltaGeometry geometry_from(const json& j) {
    models::DeltaGeometry g;
    g.diagonal_rod_mm = j.at("diagonal_rod_mm").get<double>();
    g.diagonal_rod_trim_mm = j.at("diagonal_rod_trim_mm").get<std::array<double, 3>>();
    g.radius_mm = j.at("radius_mm").get<double>();
    g.tower_angle_trim_deg = j.at("tower_angle_trim_deg").get<std::array<double, 3>>();
    g.endstop_offset_mm = j.at("endstop_offset_mm").get<std::array<double, 3>>();
    g.height_mm = j.at("height_mm").get<double>();
    return g;
}

json convergence_json(const solve::FitConvergence& c) {
    return {{"iterations", c.iterations},
            {"final_step", c.final_step},
            {"stopped_on", c.stopped_on},
            {"stopped_on_limit", c.stopped_on_limit}};
}

solve::FitConvergence convergence_from(const json& j) {
    return {j.at("iterations").get<int>(), j.at("final_step").get<double>(),
            j.at("stopped_on").get<std::string>(), j.at("stopped_on_limit").get<bool>()};
}

}  // namespace

std::string measurements_to_json(const DeltaMeasurementsRecord& r) {
    json features = json::array();
    for (const auto& f : r.features) {
        features.push_back(
            {{"id", f.id},
             {"commanded_mm", {f.commanded_mm.x, f.commanded_mm.y, f.commanded_mm.z}},
             {"measured_mm", {f.measured_mm.x, f.measured_mm.y}},
             {"sigma_mm", f.sigma_mm},
             {"seen_at_height_mm", f.seen_at_height_mm},
             {"shift_per_height", {f.shift_per_height.x, f.shift_per_height.y}},
             {"refined", f.refined},
             {"height_measured", f.height_measured},
             {"height_sigma_mm", f.height_sigma_mm},
             {"free_bead", f.free_bead},
             {"scraped", f.scraped}});
    }
    json bars = json::array();
    for (const auto& b : r.bars) {
        bars.push_back({{"tower", std::string(1, b.tower)},
                        {"commanded_from_mm", b.commanded_from_mm},
                        {"commanded_to_mm", b.commanded_to_mm},
                        {"commanded_mm", b.commanded_mm},
                        {"measured_mm", b.measured_mm},
                        {"sigma_mm", b.sigma_mm},
                        {"surface_height_mm", b.surface_height_mm}});
    }
    const json j{{"schema", kMeasurementsSchema},
                 {"machine_fingerprint", r.machine_fingerprint},
                 {"target_fingerprint", r.target_fingerprint},
                 {"photos", r.photos},
                 {"bed_scale", r.bed_scale},
                 {"heights_from_fit", r.heights_from_fit},
                 {"heights_fallback", r.heights_fallback},
                 {"bars_unmeasured", r.bars_unmeasured},
                 {"heights_unmeasured", r.heights_unmeasured},
                 {"features", features},
                 {"bars", bars}};
    return j.dump(1) + "\n";
}

DeltaMeasurementsRecord measurements_from_json(std::string_view text, const std::string& source) {
    const json j = parse_record(text, source, kMeasurementsSchema, "measurements");
    DeltaMeasurementsRecord r;
    try {
        r.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        r.target_fingerprint = j.value("target_fingerprint", "");
        if (j.contains("photos")) r.photos = j.at("photos").get<std::vector<std::string>>();
        r.bed_scale = j.value("bed_scale", 1.0);
        r.heights_from_fit = j.value("heights_from_fit", false);
        r.heights_fallback = j.value("heights_fallback", "");
        if (j.contains("bars_unmeasured"))
            r.bars_unmeasured = j.at("bars_unmeasured").get<std::vector<std::string>>();
        if (j.contains("heights_unmeasured"))
            r.heights_unmeasured = j.at("heights_unmeasured").get<std::vector<std::string>>();
        for (const auto& f : j.at("features")) {
            solve::FeatureMeasurement fm;
            fm.id = f.value("id", "");
            const auto& c = f.at("commanded_mm");
            const auto& s = f.at("measured_mm");
            fm.commanded_mm = {number(c.at(0)), number(c.at(1)), number(c.at(2))};
            fm.measured_mm = {number(s.at(0)), number(s.at(1))};
            fm.sigma_mm = number(f.at("sigma_mm"));
            if (f.contains("seen_at_height_mm")) {
                fm.seen_at_height_mm = number(f.at("seen_at_height_mm"));
                fm.shift_per_height = {number(f.at("shift_per_height").at(0)),
                                       number(f.at("shift_per_height").at(1))};
            }
            fm.refined = f.value("refined", true);
            // Files from before heights were measured have none.
            fm.height_measured = f.value("height_measured", false);
            fm.free_bead = f.value("free_bead", false);
            fm.scraped = f.value("scraped", false);
            if (fm.height_measured) {
                fm.height_sigma_mm = number(f.at("height_sigma_mm"));
                if (!(fm.height_sigma_mm >= 0))
                    throw RecordError(source + ": height_sigma_mm must not be negative");
            }
            r.features.push_back(fm);
        }
        if (j.contains("bars")) {
            for (const auto& b : j.at("bars")) {
                BarLengthMeasurement bar;
                const std::string tower = b.value("tower", "A");
                if (tower.size() != 1) throw RecordError(source + ": a bar's tower is one letter");
                bar.tower = tower[0];
                bar.commanded_from_mm = b.value("commanded_from_mm", 0.0);
                bar.commanded_to_mm = b.at("commanded_to_mm").get<double>();
                bar.commanded_mm =
                    b.value("commanded_mm", bar.commanded_to_mm - bar.commanded_from_mm);
                bar.measured_mm = b.at("measured_mm").get<double>();
                bar.sigma_mm = b.value("sigma_mm", 0.0);
                bar.surface_height_mm = b.value("surface_height_mm", 0.0);
                r.bars.push_back(bar);
            }
        }
    } catch (const json::exception& e) {
        throw RecordError(source + ": malformed measurements: " + e.what());
    }
    return r;
}

std::string result_to_json(const DeltaSolution& s) {
    const auto& fitted = s.fit.fitted;
    const auto& correction = s.fit.correction;
    json uncertainty = json::object(), held = json::array();
    for (const auto& p : s.fit.parameters) {
        uncertainty[p.name] = p.held ? json(nullptr) : json(p.uncertainty);
        if (p.held) held.push_back(p.name);
    }
    const bool fit = s.method == DeltaMethod::fit;
    const json j{{"schema", kResultSchema},
                 {"method", method_name(s.method)},
                 {"firmware", s.firmware},
                 {"machine_fingerprint", s.machine_fingerprint},
                 {"parameters_before", geometry_json(fitted.before)},
                 {"parameters_after", geometry_json(s.after)},
                 {"estimate", geometry_json(fitted.estimate)},
                 {"uncertainty", uncertainty},
                 {"observability",
                  {{"singular_values", fitted.singular_values},
                   {"condition_number", fitted.condition_number},
                   {"held", held}}},
                 {"predicted_residual_mm",
                  fit ? json{{"xy_rms", correction.predicted_xy_rms_mm},
                             {"xy_max", correction.predicted_xy_max_mm},
                             {"height_map_change_max", correction.predicted_height_change_mm},
                             {"xy_change_max", correction.predicted_xy_change_mm},
                             {"fit_rms", fitted.fit_rms_mm}}
                      : json(nullptr)},
                 {"placement",
                  {{"rotation_deg", fitted.placement.angle_rad * 180 / 3.14159265358979323846},
                   {"translation_mm",
                    {fitted.placement.translation_mm.x, fitted.placement.translation_mm.y}}}},
                 {"convergence",
                  {{"estimate", convergence_json(fitted.convergence)},
                   {"correction", fit ? convergence_json(correction.convergence) : json(nullptr)}}},
                 {"used_probe", fitted.used_probe},
                 {"heights_from", s.heights_from_probe ? "probe" : "strands"},
                 {"classic_bars", s.classic_bars},
                 {"bed",
                  {{"height_range_now_mm", correction.predicted_height_range_now_mm},
                   {"levelled", fit && correction.levels_bed}}},
                 {"commands", s.commands}};
    return j.dump(1) + "\n";
}

DeltaSolution result_from_json(std::string_view text, const std::string& source) {
    const json j = parse_record(text, source, kResultSchema, "delta result");
    DeltaSolution s;
    try {
        s.method = parse_method(j.at("method").get<std::string>());
        s.firmware = j.at("firmware").get<std::string>();
        s.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        auto& fitted = s.fit.fitted;
        auto& correction = s.fit.correction;
        fitted.before = geometry_from(j.at("parameters_before"));
        s.after = geometry_from(j.at("parameters_after"));
        fitted.estimate = geometry_from(j.at("estimate"));
        const auto& obs = j.at("observability");
        fitted.singular_values = obs.at("singular_values").get<std::vector<double>>();
        fitted.condition_number = obs.at("condition_number").get<double>();
        if (const auto& p = j.at("predicted_residual_mm"); !p.is_null()) {
            correction.predicted_xy_rms_mm = p.at("xy_rms").get<double>();
            correction.predicted_xy_max_mm = p.at("xy_max").get<double>();
            correction.predicted_height_change_mm = p.at("height_map_change_max").get<double>();
            correction.predicted_xy_change_mm = p.at("xy_change_max").get<double>();
            fitted.fit_rms_mm = p.at("fit_rms").get<double>();
        }
        fitted.placement.angle_rad =
            j.at("placement").at("rotation_deg").get<double>() * 3.14159265358979323846 / 180;
        const auto& t = j.at("placement").at("translation_mm");
        fitted.placement.translation_mm = {t.at(0).get<double>(), t.at(1).get<double>()};
        if (j.contains("convergence")) {
            const auto& c = j.at("convergence");
            fitted.convergence = convergence_from(c.at("estimate"));
            if (!c.at("correction").is_null())
                correction.convergence = convergence_from(c.at("correction"));
        }
        fitted.used_probe = j.at("used_probe").get<bool>();
        const auto heights_from = j.at("heights_from").get<std::string>();
        if (heights_from != "probe" && heights_from != "strands")
            throw RecordError(source + ": heights_from must be probe or strands, not '" +
                              heights_from + "'");
        s.heights_from_probe = heights_from == "probe";
        s.classic_bars = j.value("classic_bars", std::size_t{0});
        correction.predicted_height_range_now_mm =
            j.at("bed").at("height_range_now_mm").get<double>();
        correction.levels_bed = j.at("bed").at("levelled").get<bool>();
        correction.after = s.method == DeltaMethod::fit ? s.after : fitted.before;
        s.commands = j.at("commands").get<std::vector<std::string>>();
        // The per-parameter report: uncertainties by name as written (null: held), values from
        // the geometries.
        const auto names = solve::report_parameters(fitted, s.after);
        const auto& written = j.at("uncertainty");
        for (std::size_t k = 0; k < names.size(); ++k) {
            const auto& u = written.at(names[k].name);
            fitted.held[k] = u.is_null();
            fitted.uncertainty[k] = u.is_null() ? 0 : u.get<double>();
        }
        s.fit.parameters = solve::report_parameters(fitted, s.after);
    } catch (const json::exception& e) {
        throw RecordError(source + ": malformed delta result: " + e.what());
    } catch (const SolveError& e) {
        throw RecordError(source + ": " + e.what());
    }
    return s;
}

}  // namespace calbox::modes
