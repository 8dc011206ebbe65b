// calbox solve delta: measurements -> machine parameters -> the lines to send.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/models/delta_commands.hpp"
#include "core/solve/delta_fit.hpp"
#include "firmware/cli_args.hpp"

namespace calbox::cli {
namespace {

constexpr const char* kSolveHelp = R"(usage:
  calbox solve delta --machine printer.toml --measurements measurements.json [--probe heights.csv]
                     [--firmware marlin|rrf|klipper] [--method fit|classic] -o result.json
      Fits the delta's geometry to where its features really landed and writes the correction:
      parameters before and after, their uncertainty, what the data determine (singular values,
      condition number, parameters held), the residual predicted after correction, and the exact
      lines to send. --probe adds measured heights (CSV x,y,z: the nozzle's height over the bed
      when commanded to z = 0 there) so the height and the height map are corrected too. Without
      it, a bed the fit finds out of level by more than 0.1 mm is levelled about its centre and
      a flatter one keeps the height map it has. --method classic is the seed paper's rod-only
      correction from the bar lengths, for comparison. Refused, nothing written: measurements
      the geometry cannot explain (residual over 3 times their uncertainty), a rod or radius
      change over 2 %, a tower angle trim over 3 degrees.
)";

struct Measurements {
    std::string machine_fingerprint;
    std::vector<solve::FeatureMeasurement> features;
    std::vector<solve::BarMeasurement> bars;
};

Measurements read_measurements(const std::string& text, const std::string& path) {
    Measurements m;
    try {
        const auto j = nlohmann::json::parse(text);
        if (!j.is_object() || j.value("schema", "") != "calbox.measurements/1") {
            throw std::runtime_error(path +
                                     ": not a measurements file (schema calbox.measurements/1)");
        }
        m.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        for (const auto& f : j.at("features")) {
            solve::FeatureMeasurement fm;
            fm.id = f.value("id", "");
            const auto& c = f.at("commanded_mm");
            const auto& s = f.at("measured_mm");
            const auto number = [&](const nlohmann::json& v) {
                if (v.is_null()) return std::nan("");  // NaN is written as null; the fit refuses it
                return v.get<double>();
            };
            fm.commanded_mm = {number(c.at(0)), number(c.at(1)), number(c.at(2))};
            fm.measured_mm = {number(s.at(0)), number(s.at(1))};
            fm.sigma_mm = number(f.at("sigma_mm"));
            if (f.contains("seen_at_height_mm")) {
                fm.seen_at_height_mm = number(f.at("seen_at_height_mm"));
                fm.shift_per_height = {number(f.at("shift_per_height").at(0)),
                                       number(f.at("shift_per_height").at(1))};
            }
            m.features.push_back(fm);
        }
        if (j.contains("bars")) {
            for (const auto& b : j.at("bars"))
                m.bars.push_back({b.value("commanded_from_mm", 0.0),
                                  b.at("commanded_to_mm").get<double>(),
                                  b.at("measured_mm").get<double>()});
        }
    } catch (const nlohmann::json::exception& e) {
        throw std::runtime_error(path + ": malformed measurements: " + e.what());
    }
    return m;
}

std::vector<solve::ProbePoint> read_probe(const std::string& text, const std::string& path) {
    std::vector<solve::ProbePoint> out;
    std::istringstream in(text);
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
        ++number;
        if (line.empty() || line[0] == '#' || line[0] == 'x') continue;
        double v[3];
        char comma1 = 0, comma2 = 0;
        std::istringstream fields(line);
        if (!(fields >> v[0] >> comma1 >> v[1] >> comma2 >> v[2]) || comma1 != ',' ||
            comma2 != ',') {
            throw std::runtime_error(path + ":" + std::to_string(number) + ": expected x,y,z");
        }
        out.push_back({v[0], v[1], v[2], 0.01});
    }
    return out;
}

nlohmann::json geometry_json(const models::DeltaGeometry& g) {
    return {{"diagonal_rod_mm", g.diagonal_rod_mm},
            {"diagonal_rod_trim_mm", g.diagonal_rod_trim_mm},
            {"radius_mm", g.radius_mm},
            {"tower_angle_trim_deg", g.tower_angle_trim_deg},
            {"endstop_offset_mm", g.endstop_offset_mm},
            {"height_mm", g.height_mm}};
}

int delta(const std::vector<std::string>& words) {
    const Args args(words,
                    {"--machine", "--measurements", "--probe", "--firmware", "--method", "-o"}, {});
    if (!args.positional().empty()) throw UsageError("solve delta takes no positional argument");
    const std::string machine_path = args.require("--machine");
    const std::string out = args.require("-o");
    const auto machine =
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path);
    if (!machine.is_delta())
        throw std::runtime_error(machine_path + ": solve delta needs a delta machine, not a " +
                                 machine.kind);
    const std::string firmware = args.get("--firmware").value_or(machine.firmware);
    if (firmware != "marlin" && firmware != "rrf" && firmware != "klipper") {
        throw UsageError("--firmware must be marlin, rrf or klipper, not '" + firmware + "'");
    }
    const std::string method = args.get("--method").value_or("fit");
    if (method != "fit" && method != "classic") throw UsageError("--method must be fit or classic");
    const std::string measurements_path = args.require("--measurements");
    const auto measurements =
        read_measurements(read_input_file(measurements_path, "measurements"), measurements_path);
    if (measurements.machine_fingerprint != models::fingerprint(machine)) {
        throw std::runtime_error(measurements_path + " was made for another machine (fingerprint " +
                                 measurements.machine_fingerprint + ", " + machine_path + " is " +
                                 models::fingerprint(machine) + ")");
    }
    std::vector<solve::ProbePoint> probe;
    if (const auto p = args.get("--probe"))
        probe = read_probe(read_input_file(*p, "probe file"), *p);
    const auto fit = solve::fit_delta(machine, measurements.features, probe);
    models::DeltaGeometry after = fit.after;
    if (method == "classic") {
        after = fit.before;
        after.diagonal_rod_mm = solve::classic_rod_length_mm(*machine.delta, measurements.bars);
        if (std::abs(after.diagonal_rod_mm - fit.before.diagonal_rod_mm) /
                fit.before.diagonal_rod_mm >
            0.02) {
            throw std::runtime_error(
                "refused: the classic rod correction changes the rod by over 2 %");
        }
    }
    const auto commands = models::firmware_commands(firmware, after);
    nlohmann::json uncertainty = nlohmann::json::object(), held = nlohmann::json::array();
    for (const auto& p : fit.parameters) {
        uncertainty[p.name] = p.held ? nlohmann::json(nullptr) : nlohmann::json(p.uncertainty);
        if (p.held) held.push_back(p.name);
    }
    const nlohmann::json result{
        {"schema", "calbox.delta-result/1"},
        {"method", method},
        {"firmware", firmware},
        {"machine_fingerprint", models::fingerprint(machine)},
        {"parameters_before", geometry_json(fit.before)},
        {"parameters_after", geometry_json(after)},
        {"estimate", geometry_json(fit.estimate)},
        {"uncertainty", uncertainty},
        {"observability",
         {{"singular_values", fit.singular_values},
          {"condition_number", fit.condition_number},
          {"held", held}}},
        {"predicted_residual_mm",
         method == "fit" ? nlohmann::json{{"xy_rms", fit.predicted_xy_rms_mm},
                                          {"xy_max", fit.predicted_xy_max_mm},
                                          {"height_map_change_max", fit.predicted_height_change_mm},
                                          {"fit_rms", fit.fit_rms_mm}}
                         : nlohmann::json(nullptr)},
        {"placement",
         {{"rotation_deg", fit.placement_rotation_deg},
          {"translation_mm", {fit.placement_translation_mm.x, fit.placement_translation_mm.y}}}},
        {"used_probe", fit.used_probe},
        {"bed",
         {{"height_range_now_mm", fit.predicted_height_range_now_mm},
          {"levelled", method == "fit" && fit.levels_bed}}},
        {"commands", commands}};
    write_output_file(out, result.dump(1) + "\n");
    if (method == "fit") {
        std::printf(
            "%s: fit correction for %s, fit RMS %.4f mm; predicted XY after %.4f mm RMS, height "
            "map change %.4f mm (bed %.3f mm out of level now: %s)\n",
            out.c_str(), firmware.c_str(), fit.fit_rms_mm, fit.predicted_xy_rms_mm,
            fit.predicted_height_change_mm, fit.predicted_height_range_now_mm,
            fit.levels_bed ? "levelled" : "kept");
    } else {
        std::printf(
            "%s: classic rod correction for %s from %zu bars: rod %.3f -> %.3f mm (fitted: %.3f "
            "mm)\n",
            out.c_str(), firmware.c_str(), measurements.bars.size(), fit.before.diagonal_rod_mm,
            after.diagonal_rod_mm, fit.estimate.diagonal_rod_mm);
    }
    for (const auto& c : commands) std::printf("  %s\n", c.c_str());
    return 0;
}

}  // namespace

int run_solve(const std::vector<std::string>& words) {
    return dispatch(words, kSolveHelp, "solve", {{"delta", delta}});
}

}  // namespace calbox::cli
