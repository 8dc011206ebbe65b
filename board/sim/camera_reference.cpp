#include "board/sim/camera_reference.hpp"

#include <cmath>
#include <stdexcept>

namespace calbox::sim {
namespace {

double coefficient(const CameraIntrinsics& c, std::size_t i) {
    return i < c.distortion.size() ? c.distortion[i] : 0.0;
}

// Normalized image coordinates (x/z, y/z) -> distorted normalized coordinates.
Vec2 distort(const CameraIntrinsics& c, double x, double y) {
    if (c.model == LensModel::pinhole) {
        const double k1 = coefficient(c, 0), k2 = coefficient(c, 1), p1 = coefficient(c, 2),
                     p2 = coefficient(c, 3), k3 = coefficient(c, 4);
        const double r2 = x * x + y * y;
        const double radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3));
        return {x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
                y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y};
    }
    const double r = std::hypot(x, y);
    if (r < 1e-15) return {x, y};
    const double theta = std::atan(r), t2 = theta * theta;
    const double theta_d =
        theta *
        (1 + t2 * (coefficient(c, 0) +
                   t2 * (coefficient(c, 1) + t2 * (coefficient(c, 2) + t2 * coefficient(c, 3)))));
    return {x * theta_d / r, y * theta_d / r};
}

}  // namespace

Pose look_at_pose(const Vec3& position_mm, const Vec3& look_at_mm, double roll_deg) {
    const Vec3 z = (look_at_mm - position_mm).normalized();
    // Image down (camera +y) is the plane's -y, made perpendicular to the optical axis.
    Vec3 down = Vec3{0, -1, 0} - z * z.dot(Vec3{0, -1, 0});
    if (down.norm() < 1e-9) throw std::invalid_argument("camera looks along the plane's y axis");
    down = down.normalized();
    Vec3 right = down.cross(z);
    const double roll = radians(roll_deg);
    const Vec3 x = right * std::cos(roll) + down * std::sin(roll);
    const Vec3 y = down * std::cos(roll) - right * std::sin(roll);
    Pose pose;
    const Vec3 rows[3] = {x, y, z};
    for (int i = 0; i < 3; ++i) {
        pose.rotation.m[i][0] = rows[i].x;
        pose.rotation.m[i][1] = rows[i].y;
        pose.rotation.m[i][2] = rows[i].z;
    }
    pose.translation_mm = (pose.rotation * position_mm) * -1.0;
    return pose;
}

Pose compose(const Pose& outer, const Pose& inner) {
    Pose p;
    p.rotation = outer.rotation * inner.rotation;
    p.translation_mm = outer.apply(inner.translation_mm);
    return p;
}

Pose board_lying_on_bed(const Vec3& origin_mm, double angle_deg) {
    const double a = radians(angle_deg);
    const Vec3 columns[3] = {
        {std::cos(a), std::sin(a), 0}, {std::sin(a), -std::cos(a), 0}, {0, 0, -1}};
    Pose p;
    for (int i = 0; i < 3; ++i) {
        p.rotation.m[0][i] = columns[i].x;
        p.rotation.m[1][i] = columns[i].y;
        p.rotation.m[2][i] = columns[i].z;
    }
    p.translation_mm = origin_mm;
    return p;
}

geometry::CameraModel as_camera_model(const CameraIntrinsics& c) {
    geometry::CameraModel m;
    m.model =
        c.model == LensModel::fisheye ? geometry::LensModel::fisheye : geometry::LensModel::pinhole;
    m.image_width = c.width_px;
    m.image_height = c.height_px;
    m.camera_matrix = {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
    m.distortion = c.distortion;
    m.distortion.resize(m.model == geometry::LensModel::fisheye ? 4 : 5, 0.0);
    return m;
}

Vec2 distort_normalized(const CameraIntrinsics& c, double x, double y) {
    const Vec2 d = distort(c, x, y);
    return {c.fx * d.x + c.cx, c.fy * d.y + c.cy};
}

Vec2 undistort_pixel(const CameraIntrinsics& c, double u, double v) {
    const Vec2 target{(u - c.cx) / c.fx, (v - c.cy) / c.fy};
    Vec2 start = target;
    if (c.model == LensModel::fisheye) {
        // Start from the equidistant inverse: theta_d ~ theta.
        const double rd = std::hypot(target.x, target.y);
        if (rd > 1e-15) {
            const double r = std::tan(std::min(rd, 1.5));
            start = {target.x * r / rd, target.y * r / rd};
        }
    }
    return undistort_pixel_from(c, u, v, start);
}

Vec2 undistort_pixel_from(const CameraIntrinsics& c, double u, double v, Vec2 start) {
    const Vec2 target{(u - c.cx) / c.fx, (v - c.cy) / c.fy};
    // Newton's method on distort(x, y) = target, with a numerical Jacobian; the distortion is
    // smooth and monotonic over any usable field of view, so it converges in a few steps.
    Vec2 p = start;
    for (int iteration = 0; iteration < 30; ++iteration) {
        const Vec2 f = distort(c, p.x, p.y);
        const double ex = f.x - target.x, ey = f.y - target.y;
        if (std::abs(ex) + std::abs(ey) < 1e-15) break;
        // Within the unit circle the step is 1e-7 (hypot, the costly part, is not needed).
        const double h =
            1e-7 * (p.x * p.x + p.y * p.y < 0.99 ? 1.0 : std::max(1.0, std::hypot(p.x, p.y)));
        const Vec2 fx = distort(c, p.x + h, p.y), fy = distort(c, p.x, p.y + h);
        const double a = (fx.x - f.x) / h, b = (fy.x - f.x) / h, cc = (fx.y - f.y) / h,
                     d = (fy.y - f.y) / h;
        const double det = a * d - b * cc;
        if (std::abs(det) < 1e-300) break;
        p.x -= (d * ex - b * ey) / det;
        p.y -= (a * ey - cc * ex) / det;
    }
    return p;
}

Vec2 project_point(const CameraIntrinsics& c, const Pose& plane_to_camera, const Vec3& p) {
    const Vec3 q = plane_to_camera.apply(p);
    if (q.z <= 0) throw std::domain_error("point behind the camera");
    return distort_normalized(c, q.x / q.z, q.y / q.z);
}

}  // namespace calbox::sim
