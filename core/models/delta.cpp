#include "core/models/delta.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace calbox::models {
namespace {

constexpr std::array<double, 3> kBaseAngleDeg{210.0, 330.0, 90.0};

struct Towers {
    std::array<Eigen::Vector2d, 3> xy;
    std::array<double, 3> rod2;
};

Towers towers(const DeltaGeometry& g) {
    Towers t;
    for (int i = 0; i < 3; ++i) {
        const auto k = static_cast<std::size_t>(i);
        const double a = (kBaseAngleDeg[k] + g.tower_angle_trim_deg[k]) * std::numbers::pi / 180;
        t.xy[k] = {std::cos(a) * g.radius_mm, std::sin(a) * g.radius_mm};
        const double rod = g.diagonal_rod_mm + g.diagonal_rod_trim_mm[k];
        t.rod2[k] = rod * rod;
    }
    return t;
}

double mean(const std::array<double, 3>& v) {
    return (v[0] + v[1] + v[2]) / 3;
}

}  // namespace

std::array<double, 3> carriage_heights_mm(const DeltaGeometry& g, const geometry::Point3& p) {
    const Towers t = towers(g);
    std::array<double, 3> h{};
    for (std::size_t i = 0; i < 3; ++i) {
        const double dx = t.xy[i].x() - p.x, dy = t.xy[i].y() - p.y;
        const double under = t.rod2[i] - dx * dx - dy * dy;
        if (!(under > 0)) {
            throw UnreachableError("X" + std::to_string(p.x) + " Y" + std::to_string(p.y) +
                                   " is out of reach of tower " +
                                   std::string(1, static_cast<char>('A' + i)));
        }
        h[i] = p.z + std::sqrt(under);
    }
    return h;
}

geometry::Point3 effector_position_mm(const DeltaGeometry& g, const std::array<double, 3>& c) {
    const Towers t = towers(g);
    const Eigen::Vector3d p1(t.xy[0].x(), t.xy[0].y(), c[0]), p2(t.xy[1].x(), t.xy[1].y(), c[1]),
        p3(t.xy[2].x(), t.xy[2].y(), c[2]);
    // Trilateration in the frame of the three carriage joints (Klipper's mathutil).
    const Eigen::Vector3d ex = (p2 - p1).normalized();
    const double d = (p2 - p1).norm(), i = ex.dot(p3 - p1);
    const Eigen::Vector3d ey = (p3 - p1 - i * ex).normalized();
    const Eigen::Vector3d ez = ex.cross(ey);
    const double j = ey.dot(p3 - p1);
    const double x = (t.rod2[0] - t.rod2[1] + d * d) / (2 * d);
    const double y = (t.rod2[0] - t.rod2[2] - x * x + (x - i) * (x - i) + j * j) / (2 * j);
    const double zz = t.rod2[0] - x * x - y * y;
    if (!(zz >= 0)) throw UnreachableError("carriage heights with no effector position");
    const Eigen::Vector3d e = p1 + x * ex + y * ey - std::sqrt(zz) * ez;
    return {e.x(), e.y(), e.z()};
}

geometry::Point3 actual_position_mm(const DeltaGeometry& truth, const DeltaGeometry& firmware,
                                    const geometry::Point3& commanded) {
    const auto logical = carriage_heights_mm(firmware, commanded);
    const auto logical_home = carriage_heights_mm(firmware, {0, 0, firmware.height_mm});
    const auto true_home = carriage_heights_mm(truth, {0, 0, truth.height_mm});
    std::array<double, 3> physical{};
    for (std::size_t i = 0; i < 3; ++i) {
        // Homed: at the true endstop (true home less the true offset) lowered by the firmware's.
        const double homed =
            true_home[i] - truth.endstop_offset_mm[i] + firmware.endstop_offset_mm[i];
        physical[i] = homed + logical[i] - logical_home[i];
    }
    return effector_position_mm(truth, physical);
}

DeltaGeometry in_gauge(const DeltaGeometry& g) {
    DeltaGeometry out = g;
    const double rod = mean(g.diagonal_rod_trim_mm), angle = mean(g.tower_angle_trim_deg);
    const double top = *std::max_element(g.endstop_offset_mm.begin(), g.endstop_offset_mm.end());
    out.diagonal_rod_mm += rod;
    for (std::size_t i = 0; i < 3; ++i) {
        out.diagonal_rod_trim_mm[i] -= rod;
        out.tower_angle_trim_deg[i] -= angle;
        out.endstop_offset_mm[i] -= top;
    }
    // Lowering every carriage by the same offset after homing is lowering the home height.
    out.height_mm -= top;
    return out;
}

RrfDelta to_rrf(const DeltaGeometry& g) {
    RrfDelta r;
    for (std::size_t i = 0; i < 3; ++i) {
        r.diagonal_mm[i] = g.diagonal_rod_mm + g.diagonal_rod_trim_mm[i];
        r.endstop_adjustment_mm[i] = -g.endstop_offset_mm[i];
    }
    r.radius_mm = g.radius_mm;
    r.height_mm = g.height_mm;
    r.x_tower_angle_deg = g.tower_angle_trim_deg[0] - g.tower_angle_trim_deg[2];
    r.y_tower_angle_deg = g.tower_angle_trim_deg[1] - g.tower_angle_trim_deg[2];
    return r;
}

DeltaGeometry from_rrf(const RrfDelta& r) {
    DeltaGeometry g;
    g.diagonal_rod_mm = 0;
    for (std::size_t i = 0; i < 3; ++i) {
        g.diagonal_rod_trim_mm[i] = r.diagonal_mm[i];
        g.endstop_offset_mm[i] = -r.endstop_adjustment_mm[i];
    }
    g.radius_mm = r.radius_mm;
    g.height_mm = r.height_mm;
    g.tower_angle_trim_deg = {r.x_tower_angle_deg, r.y_tower_angle_deg, 0};
    return in_gauge(g);
}

KlipperDelta to_klipper(const DeltaGeometry& g) {
    KlipperDelta k;
    k.delta_radius_mm = g.radius_mm;
    for (std::size_t i = 0; i < 3; ++i) {
        k.arm_length_mm[i] = g.diagonal_rod_mm + g.diagonal_rod_trim_mm[i];
        k.angle_deg[i] = kBaseAngleDeg[i] + g.tower_angle_trim_deg[i];
        // Klipper's endstop is where the carriage triggers, Marlin's offset lowers it from there:
        // the nozzle over the bed centre with carriage i at its trigger height is H - offset.
        k.position_endstop_mm[i] = g.height_mm - g.endstop_offset_mm[i];
    }
    return k;
}

DeltaGeometry from_klipper(const KlipperDelta& k) {
    DeltaGeometry g;
    g.diagonal_rod_mm = 0;
    g.radius_mm = k.delta_radius_mm;
    const double height =
        std::min({k.position_endstop_mm[0], k.position_endstop_mm[1], k.position_endstop_mm[2]});
    g.height_mm = height;
    for (std::size_t i = 0; i < 3; ++i) {
        g.diagonal_rod_trim_mm[i] = k.arm_length_mm[i];
        g.tower_angle_trim_deg[i] = k.angle_deg[i] - kBaseAngleDeg[i];
        g.endstop_offset_mm[i] = height - k.position_endstop_mm[i];
    }
    return in_gauge(g);
}

}  // namespace calbox::models
