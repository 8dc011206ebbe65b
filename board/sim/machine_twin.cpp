#include "board/sim/machine_twin.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>

namespace calbox::sim {
namespace {

std::string fixed3(double v) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.3f", v);
    return buffer;
}

// Carriage height at home for a geometry: the nozzle at (0, 0, height).
std::array<double, 3> carriage_heights_at_home(const DeltaParams& p) {
    return reference_carriage_heights_mm(p, Vec3{0, 0, p.height_mm});
}

// RepRapFirmware's one diagonal per tower, as it prints them: "250.100:249.900:250.000".
std::string rrf_diagonals(const DeltaParams& p) {
    std::string out;
    for (std::size_t i = 0; i < 3; ++i) {
        if (i > 0) out += ':';
        out += fixed3(p.diagonal_rod_mm + p.diagonal_rod_trim_mm[i]);
    }
    return out;
}

}  // namespace

DeltaTwin::DeltaTwin(const DeltaParams& truth, const DeltaParams& firmware, DeltaDialect dialect)
    : truth_(truth), firmware_(firmware), stored_(firmware), dialect_(dialect) {
    for (double adj : truth.endstop_offset_mm)
        if (adj > 0) throw MachineError("true endstop offsets must be <= 0, as in Marlin");
    if (dialect_ == DeltaDialect::marlin) {
        for (double adj : firmware.endstop_offset_mm)
            if (adj > 0) throw MachineError("firmware endstop offsets must be <= 0 (M666)");
    }
}

void DeltaTwin::home() {
    // The true geometry's parameters are those with which the firmware would be exact: with
    // them, the physical endstop of tower i triggers at the true home height less the true offset.
    const auto true_home = carriage_heights_at_home(truth_);
    home_logical_mm_ = carriage_heights_at_home(firmware_);
    for (int i = 0; i < 3; ++i) {
        const double endstop = true_home[i] - truth_.endstop_offset_mm[i];
        home_physical_mm_[i] = endstop + firmware_.endstop_offset_mm[i];
    }
    homed_ = true;
}

Vec3 DeltaTwin::actual_position_mm(const Vec3& commanded) const {
    if (!homed_) throw MachineError("move before homing (G28)");
    const auto logical = reference_carriage_heights_mm(firmware_, commanded);
    std::array<double, 3> physical{};
    for (int i = 0; i < 3; ++i)
        physical[i] = home_physical_mm_[i] + (logical[i] - home_logical_mm_[i]);
    return reference_effector_position_mm(truth_, physical);
}

void DeltaTwin::zero_height_at_centre() {
    const bool was_homed = homed_;
    home();
    // Moving every carriage by the same amount moves the nozzle straight up or down by it.
    const double z = actual_position_mm({0, 0, 0}).z;
    // A longer height makes the firmware travel further down from home for the same Z.
    firmware_.height_mm += z;
    stored_ = firmware_;
    home();
    homed_ = was_homed;
}

template <typename Settings>
void DeltaTwin::level(const std::vector<Vec3>& points, int unknowns, Settings free) {
    const DeltaParams start = firmware_;
    const bool was_homed = homed_;
    const auto heights = [&](const Eigen::VectorXd& v) {
        firmware_ = start;
        free(v, firmware_);
        home();
        Eigen::VectorXd z(static_cast<Eigen::Index>(points.size()));
        for (std::size_t i = 0; i < points.size(); ++i)
            z[static_cast<Eigen::Index>(i)] = actual_position_mm(points[i]).z;
        return z;
    };
    Eigen::VectorXd v = Eigen::VectorXd::Zero(unknowns);
    for (int iteration = 0; iteration < 8; ++iteration) {
        const Eigen::VectorXd z = heights(v);
        Eigen::MatrixXd j(z.size(), unknowns);
        for (int k = 0; k < unknowns; ++k) {
            Eigen::VectorXd step = v;
            step[k] += 1e-4;
            j.col(k) = (heights(step) - z) / 1e-4;
        }
        v -= j.completeOrthogonalDecomposition().solve(z);
    }
    heights(v);
    stored_ = firmware_;
    homed_ = was_homed;
}

namespace {
// Endstop offsets a, b relative to tower C's and a height change, kept <= 0 as Marlin wants by
// moving the common part into the height (the same machine).
void set_endstops(DeltaParams& p, double a, double b, double height_change) {
    const double top = std::max({a, b, 0.0});
    p.height_mm += height_change - top;
    p.endstop_offset_mm = {a - top, b - top, -top};
}
void set_endstops_from(DeltaParams& p, const Eigen::VectorXd& v) {
    const auto& e = p.endstop_offset_mm;
    set_endstops(p, e[0] - e[2] + v[0], e[1] - e[2] + v[1], v[2] + e[2]);
}
}  // namespace

void DeltaTwin::level_by_paper(double r) {
    std::vector<Vec3> points{{0, 0, 0}};
    for (const double deg : {210.0, 330.0, 90.0})
        points.push_back({r * std::cos(radians(deg)), r * std::sin(radians(deg)), 0});
    level(points, 4, [](const Eigen::VectorXd& v, DeltaParams& p) {
        p.radius_mm += v[3];
        set_endstops_from(p, v);
    });
}

void DeltaTwin::level_by_probe(double r, double inner) {
    std::vector<Vec3> points{{0, 0, 0}};
    for (int k = 0; k < 12; ++k)
        points.push_back({r * std::cos(radians(30.0 * k)), r * std::sin(radians(30.0 * k)), 0});
    for (int k = 0; k < 6; ++k)
        points.push_back({inner * std::cos(radians(60.0 * k) + 0.5),
                          inner * std::sin(radians(60.0 * k) + 0.5), 0});
    level(points, 6, [](const Eigen::VectorXd& v, DeltaParams& p) {
        p.radius_mm += v[3];
        p.tower_angle_trim_deg[0] += v[4];
        p.tower_angle_trim_deg[1] += v[5];
        set_endstops_from(p, v);
    });
}

std::vector<std::string> MachineTwin::probe_bed(const gcode::Line& /*line*/, Vec3& /*at*/) {
    throw MachineError("G30: this machine has no bed probe");
}

Vec3 MachineTwin::probe_down(const Vec3& /*from*/, double /*to_z*/) {
    throw MachineError("G38.2: this machine has no touch probe");
}

std::vector<std::string> DeltaTwin::probe_bed(const gcode::Line& line, Vec3& at) {
    if (!homed_) throw MachineError("G30 before homing (G28)");
    if (dialect_ == DeltaDialect::rrf && line.value('S') != -1.0)
        throw MachineError(
            "the twin's RepRapFirmware probes with G30 S-1 only (report, no change)");
    // The commanded Z where the nozzle meets the bed: the height there, on the slope the
    // geometry gives it (about one, so a few steps converge far below the probe's noise).
    double touch_z = 0;
    for (int step = 0; step < 4; ++step) touch_z -= actual_position_mm({at.x, at.y, touch_z}).z;
    touch_z += std::normal_distribution<double>(0, 0.004)(probe_noise_);
    char reply[120];
    if (dialect_ == DeltaDialect::rrf)
        std::snprintf(reply, sizeof reply, "Stopped at height %.3f mm", touch_z);
    else if (dialect_ == DeltaDialect::klipper)
        // The toolhead's height when the probe, its z_offset above the nozzle, triggered.
        std::snprintf(reply, sizeof reply, "// probe at %.3f,%.3f is z=%.6f", at.x, at.y,
                      touch_z + klipper_probe_z_offset_mm_);
    else
        std::snprintf(reply, sizeof reply, "Bed X: %.2f Y: %.2f Z: %.2f", at.x, at.y, touch_z);
    at.z = touch_z + 5;  // raised after probing
    return {reply};
}

std::optional<std::vector<std::string>> DeltaTwin::settings_command(const gcode::Line& line) {
    if (dialect_ == DeltaDialect::rrf) return rrf_settings_command(line);
    if (dialect_ == DeltaDialect::klipper) return std::nullopt;
    if (line.is('M', 665)) {
        const auto set = [&](char letter, double& field) {
            if (const auto v = line.value(letter)) field = *v;
        };
        set('H', firmware_.height_mm);
        set('L', firmware_.diagonal_rod_mm);
        set('R', firmware_.radius_mm);
        set('X', firmware_.tower_angle_trim_deg[0]);
        set('Y', firmware_.tower_angle_trim_deg[1]);
        set('Z', firmware_.tower_angle_trim_deg[2]);
        set('A', firmware_.diagonal_rod_trim_mm[0]);
        set('B', firmware_.diagonal_rod_trim_mm[1]);
        set('C', firmware_.diagonal_rod_trim_mm[2]);
        if (!(firmware_.diagonal_rod_mm > firmware_.radius_mm) || !(firmware_.radius_mm > 0)) {
            throw MachineError("M665 gives an impossible geometry (rod must exceed radius)");
        }
        homed_ = false;  // Marlin's recalc_delta_settings() marks every axis unhomed
        return std::vector<std::string>{"ok"};
    }
    if (line.is('M', 666)) {
        // Marlin accepts only offsets <= 0 and applies them at the next G28.
        bool refused = false;
        const char letters[3] = {'X', 'Y', 'Z'};
        for (int i = 0; i < 3; ++i) {
            if (const auto v = line.value(letters[i])) {
                if (*v > 0) {
                    refused = true;
                } else {
                    firmware_.endstop_offset_mm[i] = *v;
                }
            }
        }
        if (refused) return std::vector<std::string>{"?M666 offsets must be <= 0", "ok"};
        return std::vector<std::string>{"ok"};
    }
    if (line.is('M', 500)) {
        stored_ = firmware_;
        return std::vector<std::string>{"echo:Settings Stored", "ok"};
    }
    if (line.is('M', 503)) {
        auto lines = marlin_delta_report(firmware_);
        lines.emplace_back("ok");
        return lines;
    }
    return std::nullopt;
}

std::optional<std::vector<std::string>> DeltaTwin::rrf_settings_command(const gcode::Line& line) {
    if (line.is('M', 665)) {
        if (line.parameters.empty()) {
            // As LinearDeltaKinematics::Configure prints it; the degree sign in UTF-8.
            std::string report = "Diagonals " + rrf_diagonals(firmware_);
            report += ", delta radius " + fixed3(firmware_.radius_mm) + ", homed height " +
                      fixed3(firmware_.height_mm) + ", bed radius 85.0";
            const char* axes[3] = {", X ", ", Y ", ", Z "};
            for (int i = 0; i < 3; ++i)
                report += axes[i] + fixed3(firmware_.tower_angle_trim_deg[i]) + "\xC2\xB0";
            return std::vector<std::string>{report, "ok"};
        }
        const auto rods = line.values('L');
        if (!rods.empty()) {
            if (rods.size() != 1 && rods.size() != 3)
                return std::vector<std::string>{"Error: M665: give 1 or 3 diagonals", "ok"};
            firmware_.diagonal_rod_mm = rods[0];
            for (std::size_t i = 0; i < 3; ++i)
                firmware_.diagonal_rod_trim_mm[i] = rods[std::min(i, rods.size() - 1)] - rods[0];
        }
        const auto set = [&](char letter, double& field) {
            if (const auto v = line.value(letter)) field = *v;
        };
        set('R', firmware_.radius_mm);
        set('H', firmware_.height_mm);
        set('X', firmware_.tower_angle_trim_deg[0]);
        set('Y', firmware_.tower_angle_trim_deg[1]);
        set('Z', firmware_.tower_angle_trim_deg[2]);
        homed_ = false;  // a kinematics change leaves the towers unhomed
        return std::vector<std::string>{"ok"};
    }
    if (line.is('M', 666)) {
        if (line.parameters.empty()) {
            char report[160];
            std::snprintf(report, sizeof report,
                          "Endstop adjustments X%.2f Y%.2f Z%.2f, tilt X0.00%% Y0.00%%",
                          0.0 - firmware_.endstop_offset_mm[0],  // never "-0.00"
                          0.0 - firmware_.endstop_offset_mm[1],
                          0.0 - firmware_.endstop_offset_mm[2]);
            return std::vector<std::string>{report, "ok"};
        }
        for (const char tilt : {'A', 'B'}) {
            if (line.value(tilt).value_or(0) != 0)
                return std::vector<std::string>{"Error: the twin has no bed tilt", "ok"};
        }
        const char letters[3] = {'X', 'Y', 'Z'};
        for (int i = 0; i < 3; ++i)
            if (const auto v = line.value(letters[i])) firmware_.endstop_offset_mm[i] = -*v;
        return std::vector<std::string>{"ok"};
    }
    if (line.is('M', 500)) {
        stored_ = firmware_;
        return std::vector<std::string>{"ok"};
    }
    return std::nullopt;
}

std::vector<std::string> DeltaTwin::stored_settings_commands() const {
    const DeltaParams& p = stored_;
    if (dialect_ == DeltaDialect::marlin) {
        auto lines = marlin_delta_report(p);
        std::vector<std::string> commands;
        for (auto& l : lines)
            if (l.rfind("echo:  M", 0) == 0) commands.push_back(l.substr(7));
        return commands;
    }
    std::string m665 = "M665 L" + rrf_diagonals(p);
    m665 += " R" + fixed3(p.radius_mm) + " H" + fixed3(p.height_mm) + " X" +
            fixed3(p.tower_angle_trim_deg[0]) + " Y" + fixed3(p.tower_angle_trim_deg[1]) + " Z" +
            fixed3(p.tower_angle_trim_deg[2]);
    return {m665, "M666 X" + fixed3(0.0 - p.endstop_offset_mm[0]) + " Y" +
                      fixed3(0.0 - p.endstop_offset_mm[1]) + " Z" +
                      fixed3(0.0 - p.endstop_offset_mm[2])};
}

std::vector<std::string> marlin_delta_report(const DeltaParams& p) {
    return {"echo:; Endstop adjustment:",
            "echo:  M666 X" + fixed3(p.endstop_offset_mm[0]) + " Y" +
                fixed3(p.endstop_offset_mm[1]) + " Z" + fixed3(p.endstop_offset_mm[2]),
            "echo:; Delta config:",
            "echo:  M665 L" + fixed3(p.diagonal_rod_mm) + " R" + fixed3(p.radius_mm) + " H" +
                fixed3(p.height_mm) + " X" + fixed3(p.tower_angle_trim_deg[0]) + " Y" +
                fixed3(p.tower_angle_trim_deg[1]) + " Z" + fixed3(p.tower_angle_trim_deg[2]) +
                " A" + fixed3(p.diagonal_rod_trim_mm[0]) + " B" +
                fixed3(p.diagonal_rod_trim_mm[1]) + " C" + fixed3(p.diagonal_rod_trim_mm[2])};
}

Vec3 CartesianTwin::actual_position_mm(const Vec3& c) const {
    if (!homed_) throw MachineError("move before homing (G28)");
    const double lean = std::tan(radians(truth_.squareness_error_deg));
    // The motors' commanded travel, then the machine's errors on it.
    const double x = (c.x - firmware_.xy_skew * c.y) * firmware_.travel_x;
    const double y = c.y * firmware_.travel_y;
    return {x * (1 + truth_.scale_error_x) + y * (1 + truth_.scale_error_y) * lean,
            y * (1 + truth_.scale_error_y), c.z};
}

std::optional<std::vector<std::string>> CartesianTwin::settings_command(const gcode::Line& line) {
    if (grbl_ && (line.is('G', 17) || line.is('M', 2) || line.is('M', 30)))
        return std::vector<std::string>{};
    if (line.is('M', 500)) return std::vector<std::string>{"echo:Settings Stored", "ok"};
    if (line.is('M', 503)) return std::vector<std::string>{"echo:; (no geometry settings)", "ok"};
    return std::nullopt;
}

std::optional<std::vector<std::string>> CartesianTwin::system_command(std::string_view text) {
    if (!grbl_ || text != "$#") return std::nullopt;
    return grbl_offsets_report(0, 0);
}

std::vector<std::string> grbl_offsets_report(double g54_x_mm, double g54_y_mm, double g54_z_mm) {
    char line[112];
    std::snprintf(line, sizeof line, "[G54:%.3f,%.3f,%.3f]", g54_x_mm, g54_y_mm, g54_z_mm);
    std::vector<std::string> report{line};
    for (const char* other : {"G55", "G56", "G57", "G58", "G59", "G28", "G30"})
        report.push_back(std::string("[") + other + ":0.000,0.000,0.000]");
    report.insert(report.end(),
                  {"[G92:0.000,0.000,0.000]", "[TLO:0.000]", "[PRB:0.000,0.000,0.000:0]", "ok"});
    return report;
}

}  // namespace calbox::sim
