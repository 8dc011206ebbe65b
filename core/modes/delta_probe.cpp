#include "core/modes/delta_probe.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <initializer_list>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "core/models/delta.hpp"
#include "core/modes/record_error.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {
namespace {

std::string lower(std::string_view s) {
    std::string out(s);
    std::transform(out.begin(), out.end(), out.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return out;
}

using models::number_after;

// Marlin's "Bed X: 10.00 Y: -20.00 Z: 0.12" (older releases: "Bed x: 10 y: .. z: .."), after
// whatever a host put before it, as a probe point: the bed's height there negated is the
// nozzle's gap at commanded Z = 0. Empty for other lines; throws std::invalid_argument for one
// that starts so but does not hold three numbers.
std::optional<solve::ProbePoint> marlin_probe_point(const std::string& text, double sigma_mm) {
    const std::string line = lower(text);
    const auto at = line.find("bed x:");
    if (at == std::string::npos) return std::nullopt;
    const auto x = number_after(line, "x:", at);
    const auto y = number_after(line, " y:", at);
    const auto z = number_after(line, " z:", at);
    if (!x || !y || !z)
        throw std::invalid_argument("a probe report line without its X, Y and Z: '" + text + "'");
    return solve::ProbePoint{*x, *y, -*z, sigma_mm};
}

// Klipper's "// probe at 10.000,-20.000 is z=1.234567": the toolhead's height when the probe
// triggered, the probe's z_offset above the bed there; the gap at commanded Z = 0 is the offset
// less that height.
std::optional<solve::ProbePoint> klipper_probe_point(const std::string& text, double z_offset_mm,
                                                     double sigma_mm) {
    const std::string line = lower(text);
    const auto at = line.find("probe at ");
    if (at == std::string::npos || line.find(" is z=", at) == std::string::npos)
        return std::nullopt;
    char* end = nullptr;
    const double x = std::strtod(line.c_str() + at + 9, &end);
    const bool comma = end != nullptr && *end == ',';
    const double y = comma ? std::strtod(end + 1, &end) : 0;
    const auto z = number_after(line, " is z=", at);
    if (!comma || !z || !std::isfinite(x) || !std::isfinite(y))
        throw std::invalid_argument("a probe report line without its X, Y and Z: '" + text + "'");
    return solve::ProbePoint{x, y, z_offset_mm - *z, sigma_mm};
}

}  // namespace

std::vector<geometry::Point2> probe_points(const models::ProbeSettings& probe) {
    std::vector<geometry::Point2> out{{0, 0}};
    // Tower A stands at 210 degrees; every 30 degrees from it on the rim, every 60 inside.
    for (const auto& [count, radius] : {std::pair{6, probe.radius_mm / 2}, {12, probe.radius_mm}}) {
        for (int i = 0; i < count; ++i) {
            const double a = (210.0 + 360.0 * i / count) * std::numbers::pi / 180;
            out.push_back({radius * std::cos(a), radius * std::sin(a)});
        }
    }
    return out;
}

std::vector<std::string> probe_job(const std::string& firmware,
                                   const std::vector<geometry::Point2>& points) {
    std::vector<std::string> job{"G28"};
    for (const auto& p : points) {
        const std::string xy = " X" + number_text("%.2f", p.x) + " Y" + number_text("%.2f", p.y);
        if (firmware == "marlin") {
            job.push_back("G30" + xy);
        } else if (firmware == "rrf") {
            job.push_back("G1" + xy + " Z5 F6000");
            job.emplace_back("G30 S-1");
        } else if (firmware == "klipper") {
            job.push_back("G1" + xy + " Z5 F6000");
            job.emplace_back("PROBE");
        } else {
            throw std::invalid_argument("no probe job for firmware '" + firmware + "'");
        }
    }
    job.emplace_back("G28");
    return job;
}

std::vector<solve::ProbePoint> probe_from_replies(const std::string& firmware,
                                                  const std::vector<geometry::Point2>& points,
                                                  const std::vector<std::string>& replies,
                                                  double sigma_mm,
                                                  std::optional<double> klipper_z_offset_mm) {
    if (firmware != "marlin" && firmware != "rrf" && firmware != "klipper")
        throw std::invalid_argument("no probe report for firmware '" + firmware + "'");
    if (firmware == "klipper" && !klipper_z_offset_mm)
        throw std::invalid_argument(
            "Klipper's probe reports need its z_offset ([probe] or [bltouch] in printer.cfg)");
    std::vector<solve::ProbePoint> out;
    for (const auto& reply : replies) {
        if (firmware == "marlin") {
            if (const auto p = marlin_probe_point(reply, sigma_mm)) out.push_back(*p);
            continue;
        }
        if (firmware == "klipper") {
            if (const auto p = klipper_probe_point(reply, *klipper_z_offset_mm, sigma_mm))
                out.push_back(*p);
            continue;
        }
        const std::string line = lower(reply);
        if (line.find("stopped at height") == std::string::npos) continue;
        const auto z = number_after(line, "stopped at height");
        if (!z) throw std::invalid_argument("a probe report without its height: '" + reply + "'");
        out.push_back({0, 0, -*z, sigma_mm});
    }
    if (out.size() != points.size())
        throw std::invalid_argument("the printer reported " + std::to_string(out.size()) +
                                    " probe height(s) for " + std::to_string(points.size()) +
                                    " points");
    for (std::size_t i = 0; i < points.size(); ++i) {
        const auto& asked = points[i];
        auto& got = out[i];
        if (firmware == "rrf") {
            got.x_mm = asked.x, got.y_mm = asked.y;  // its report says the height alone
            continue;
        }
        // Marlin and Klipper print the point; one far from where the box asked is another
        // command's report, or a probe moved by its offset.
        if (std::hypot(got.x_mm - asked.x, got.y_mm - asked.y) > 0.5)
            throw std::invalid_argument(
                "probe point " + std::to_string(i + 1) + " was reported at (" +
                number_text("%.2f", got.x_mm) + ", " + number_text("%.2f", got.y_mm) +
                ") where the box asked for (" + number_text("%.2f", asked.x) + ", " +
                number_text("%.2f", asked.y) + ")");
    }
    return out;
}

namespace {

// RepRapFirmware's height map (heightmap.csv, written by G29): a title line, the grid's header
// (xmin,xmax,ymin,ymax,radius,xspacing,yspacing,xnum,ynum) and its values, then a row of heights
// per y from ymin up. A height is where the probe found the bed against the homed frame, so the
// gap is its negation; points beyond the probing radius were not probed (RRF writes them 0).
std::vector<solve::ProbePoint> rrf_height_map(std::string_view text, const std::string& source,
                                              double sigma_mm) {
    std::istringstream in{std::string(text)};
    std::string title, names, header;
    std::getline(in, title);
    std::getline(in, names);
    std::getline(in, header);
    std::replace(header.begin(), header.end(), ',', ' ');
    std::istringstream h(header);
    double xmin = 0, xmax = 0, ymin = 0, ymax = 0, radius = 0, dx = 0, dy = 0;
    int columns = 0, rows = 0;
    if (!(h >> xmin >> xmax >> ymin >> ymax >> radius >> dx >> dy >> columns >> rows) ||
        columns < 1 || rows < 1 || columns > 1000 || rows > 1000 || !(dx > 0) || !(dy > 0))
        throw RecordError(source + ":3: not a RepRapFirmware height map header");
    std::vector<solve::ProbePoint> out;
    std::string line;
    for (int r = 0; r < rows; ++r) {
        if (!std::getline(in, line))
            throw RecordError(source + ": the height map has " + std::to_string(r) + " of its " +
                              std::to_string(rows) + " rows");
        std::replace(line.begin(), line.end(), ',', ' ');
        std::istringstream values(line);
        for (int c = 0; c < columns; ++c) {
            double z = 0;
            if (!(values >> z))
                throw RecordError(source + ":" + std::to_string(4 + r) + ": expected " +
                                  std::to_string(columns) + " heights");
            const double x = xmin + c * dx, y = ymin + r * dy;
            if (radius > 0 && std::hypot(x, y) > radius + 1e-9) continue;
            out.push_back({x, y, -z, sigma_mm});
        }
    }
    return out;
}

}  // namespace

namespace {

struct G33Key {
    const char* key;   // as the line prints it
    const char* name;  // as a refusal names it
};
// The numbers after `keys` on one of G33's lines, into `into` on; throws RecordError naming the
// first one missing.
void take_g33_numbers(const std::string& line, std::initializer_list<G33Key> keys,
                      const std::string& source, double* into) {
    for (const auto& k : keys) {
        const auto v = number_after(line, k.key);
        if (!v) throw RecordError(source + ": a G33 line without its " + k.name);
        *into++ = *v;
    }
}

std::vector<solve::ProbePoint> g33_report(std::string_view text, const std::string& source,
                                          std::optional<double> radius_mm, double sigma_mm) {
    if (!radius_mm || !(*radius_mm > 0))
        throw RecordError(source +
                          ": G33's report does not say where it probed: give --probe-radius MM "
                          "(Marlin's DELTA_CALIBRATION_RADIUS)");
    struct Block {
        std::string geometry;  // the .Height and .Tower angle lines printed before it
        std::array<double, 7> z{};
    };
    std::vector<Block> blocks;
    std::string geometry, last_geometry;
    std::istringstream in{std::string(text)};
    std::string line;
    std::optional<Block> open;
    while (std::getline(in, line)) {
        if (line.find(".Height:") != std::string::npos) {
            geometry = line.substr(line.find(".Height:"));
            last_geometry = geometry;
        } else if (line.find(".Tower angle") != std::string::npos) {
            geometry += line.substr(line.find(".Tower angle"));
            last_geometry = geometry;
        } else if (auto c = number_after(line, " c:")) {
            open = Block{geometry, {}};
            open->z[0] = *c;
            take_g33_numbers(line, {{" x:", "x"}, {" y:", "y"}, {" z:", "z"}}, source, &open->z[1]);
        } else if (open && line.find("yz:") != std::string::npos) {
            take_g33_numbers(line, {{"yz:", "yz:"}, {"zx:", "zx:"}, {"xy:", "xy:"}}, source,
                             &open->z[4]);
            blocks.push_back(*open);
            open.reset();
        }
    }
    const Block* chosen = nullptr;
    for (const auto& b : blocks)
        if (b.geometry == last_geometry) chosen = &b;
    if (chosen == nullptr)
        throw RecordError(source +
                          ": no G33 probe block measured under the geometry the run "
                          "ended with (G33 V2 prints them)");
    // Towards towers X, Y, Z (210, 330, 90 degrees), then opposite them (30, 150, 270).
    const double angles_deg[6] = {210, 330, 90, 30, 150, 270};
    std::vector<solve::ProbePoint> out{{0, 0, -chosen->z[0], sigma_mm}};
    for (std::size_t i = 0; i < 6; ++i) {
        const double a = angles_deg[i] * 3.14159265358979323846 / 180;
        out.push_back(
            {*radius_mm * std::cos(a), *radius_mm * std::sin(a), -chosen->z[1 + i], sigma_mm});
    }
    return out;
}

}  // namespace

std::vector<solve::ProbePoint> probe_from_file(std::string_view text, const std::string& source,
                                               std::optional<double> g33_radius_mm) {
    constexpr double kSigmaMm = 0.01;
    if (text.find(" c:") != std::string_view::npos && text.find("yz:") != std::string_view::npos &&
        text.find("G33") != std::string_view::npos)
        return g33_report(text, source, g33_radius_mm, kSigmaMm);
    if (text.rfind("RepRapFirmware height map", 0) == 0)
        return rrf_height_map(text, source, kSigmaMm);
    // Klipper's printer.cfg with its saved [delta_calibrate] (its includes are not needed: the
    // block and the geometry are in the file SAVE_CONFIG writes).
    if (text.find("#*# [delta_calibrate]") != std::string_view::npos) {
        try {
            return klipper_calibrate_probe(
                models::read_klipper_config(source, std::string(text),
                                            [](const std::string&) { return std::nullopt; }),
                source);
        } catch (const models::ImportError& e) {
            throw RecordError(e.what());
        }
    }
    // A console log is told by its report lines: the rest of it is the printer's chatter.
    const bool log = lower(text).find("bed x:") != std::string::npos;
    std::vector<solve::ProbePoint> out;
    std::istringstream in{std::string(text)};
    std::string line;
    int number_of_line = 0;
    while (std::getline(in, line)) {
        ++number_of_line;
        const std::string where = source + ":" + std::to_string(number_of_line);
        if (log) {
            try {
                if (const auto p = marlin_probe_point(line, kSigmaMm)) out.push_back(*p);
            } catch (const std::invalid_argument& e) {
                throw RecordError(where + ": " + e.what());
            }
            continue;
        }
        if (line.empty() || line[0] == '#' || line[0] == 'x') continue;
        double v[3];
        char comma1 = 0, comma2 = 0;
        std::istringstream fields(line);
        if (!(fields >> v[0] >> comma1 >> v[1] >> comma2 >> v[2]) || comma1 != ',' ||
            comma2 != ',') {
            throw RecordError(where + ": expected x,y,z (or a Marlin log's \"Bed X:\" lines)");
        }
        out.push_back({v[0], v[1], v[2], kSigmaMm});
    }
    if (out.empty()) throw RecordError(source + ": no probe heights");
    return out;
}

std::vector<solve::ProbePoint> klipper_calibrate_probe(const models::KlipperConfig& config,
                                                       const std::string& source) {
    if (config.saved_probe.empty())
        throw RecordError(source + ": no saved [delta_calibrate] heights");
    if (!config.steps_per_mm)
        throw RecordError(source + ": no rotation_distance and microsteps in [stepper_a/b/c]");
    const auto geometry = models::from_klipper(config.delta);
    std::vector<solve::ProbePoint> out;
    for (const auto& point : config.saved_probe) {
        std::array<double, 3> carriage{};
        for (std::size_t i = 0; i < 3; ++i) {
            // Klipper keeps each position as steps below the tower's endstop, which lies
            // position_endstop + sqrt(arm^2 - radius^2) up the tower in the saved geometry.
            const double arm = config.delta.arm_length_mm[i], radius = config.delta.delta_radius_mm;
            carriage[i] = config.delta.position_endstop_mm[i] +
                          std::sqrt(arm * arm - radius * radius) -
                          point.steps_below_endstop[i] / (*config.steps_per_mm)[i];
        }
        const auto effector = models::effector_position_mm(geometry, carriage);
        out.push_back({effector.x, effector.y, point.height_mm - effector.z, 0.01});
    }
    return out;
}

std::string probe_to_csv(const std::vector<solve::ProbePoint>& probe) {
    std::string csv = "x,y,z\n";
    for (const auto& p : probe)
        csv += number_text("%.3f", p.x_mm) + "," + number_text("%.3f", p.y_mm) + "," +
               number_text("%.4f", p.z_mm) + "\n";
    return csv;
}

}  // namespace calbox::modes
