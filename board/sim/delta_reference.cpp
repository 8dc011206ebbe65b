#include "board/sim/delta_reference.hpp"

#include <cmath>
#include <string>

namespace calbox::sim {

std::array<Tower, 3> towers_of(const DeltaParams& p) {
    constexpr std::array<double, 3> base_angle_deg{210.0, 330.0, 90.0};
    std::array<Tower, 3> t{};
    for (int i = 0; i < 3; ++i) {
        const double a = radians(base_angle_deg[i] + p.tower_angle_trim_deg[i]);
        t[i] = Tower{std::cos(a) * p.radius_mm, std::sin(a) * p.radius_mm,
                     p.diagonal_rod_mm + p.diagonal_rod_trim_mm[i]};
    }
    return t;
}

std::array<double, 3> reference_carriage_heights_mm(const DeltaParams& p, const Vec3& nozzle) {
    const auto towers = towers_of(p);
    std::array<double, 3> h{};
    for (int i = 0; i < 3; ++i) {
        const double dx = towers[i].x_mm - nozzle.x, dy = towers[i].y_mm - nozzle.y;
        const double under_root = towers[i].rod_mm * towers[i].rod_mm - dx * dx - dy * dy;
        if (!(under_root > 0)) {
            throw OutOfReach("point X" + std::to_string(nozzle.x) + " Y" +
                             std::to_string(nozzle.y) + " is out of reach of tower " +
                             std::string(1, char('A' + i)));
        }
        h[i] = nozzle.z + std::sqrt(under_root);
    }
    return h;
}

Vec3 reference_effector_position_mm(const DeltaParams& p, const std::array<double, 3>& carriage) {
    const auto towers = towers_of(p);
    const Vec3 s1{towers[0].x_mm, towers[0].y_mm, carriage[0]};
    const Vec3 s2{towers[1].x_mm, towers[1].y_mm, carriage[1]};
    const Vec3 s3{towers[2].x_mm, towers[2].y_mm, carriage[2]};
    const double r1 = towers[0].rod_mm * towers[0].rod_mm;
    const double r2 = towers[1].rod_mm * towers[1].rod_mm;
    const double r3 = towers[2].rod_mm * towers[2].rod_mm;
    // Klipper's trilateration: a frame with ex towards sphere 2 and ey in the plane of the three.
    const Vec3 s21 = s2 - s1, s31 = s3 - s1;
    const double d = s21.norm();
    const Vec3 ex = s21 * (1.0 / d);
    const double i = ex.dot(s31);
    const Vec3 ey = (s31 - ex * i).normalized();
    const Vec3 ez = ex.cross(ey);
    const double j = ey.dot(s31);
    const double x = (r1 - r2 + d * d) / (2 * d);
    const double y = (r1 - r3 - x * x + (x - i) * (x - i) + j * j) / (2 * j);
    const double zz = r1 - x * x - y * y;
    if (!(zz >= 0)) throw OutOfReach("carriage heights have no effector position");
    // ez points up (the towers are counter-clockwise), the effector hangs below the carriages.
    return s1 + ex * x + ey * y + ez * (-std::sqrt(zz));
}

}  // namespace calbox::sim
