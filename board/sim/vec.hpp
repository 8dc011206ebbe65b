#pragma once
// The twin's own small vector type: board/sim keeps its arithmetic independent of the code
// it judges.
#include <algorithm>
#include <cmath>

namespace calbox::sim {

struct Vec3 {
    double x = 0, y = 0, z = 0;
    Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    double dot(const Vec3& o) const { return x * o.x + y * o.y + z * o.z; }
    Vec3 cross(const Vec3& o) const {
        return {y * o.z - z * o.y, z * o.x - x * o.z, x * o.y - y * o.x};
    }
    double norm() const { return std::sqrt(dot(*this)); }
    Vec3 normalized() const { return *this * (1.0 / norm()); }
};

// Row-major 3x3 rotation.
struct Mat3 {
    double m[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    Vec3 operator*(const Vec3& v) const {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
    }
    Mat3 operator*(const Mat3& o) const {
        Mat3 r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                r.m[i][j] = m[i][0] * o.m[0][j] + m[i][1] * o.m[1][j] + m[i][2] * o.m[2][j];
        return r;
    }
    Mat3 transposed() const {
        Mat3 r;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) r.m[i][j] = m[j][i];
        return r;
    }
};

// Rodrigues: rotation vector (radians) -> matrix, OpenCV's convention.
inline Mat3 rotation_from_vector(const Vec3& r) {
    const double theta = r.norm();
    Mat3 out;
    if (theta < 1e-15) return out;
    const Vec3 k = r * (1.0 / theta);
    const double c = std::cos(theta), s = std::sin(theta), v = 1 - c;
    out.m[0][0] = c + k.x * k.x * v;
    out.m[0][1] = k.x * k.y * v - k.z * s;
    out.m[0][2] = k.x * k.z * v + k.y * s;
    out.m[1][0] = k.y * k.x * v + k.z * s;
    out.m[1][1] = c + k.y * k.y * v;
    out.m[1][2] = k.y * k.z * v - k.x * s;
    out.m[2][0] = k.z * k.x * v - k.y * s;
    out.m[2][1] = k.z * k.y * v + k.x * s;
    out.m[2][2] = c + k.z * k.z * v;
    return out;
}

inline Vec3 vector_from_rotation(const Mat3& R) {
    const double cos_theta = std::clamp((R.m[0][0] + R.m[1][1] + R.m[2][2] - 1) / 2, -1.0, 1.0);
    const double theta = std::acos(cos_theta);
    const Vec3 axis{R.m[2][1] - R.m[1][2], R.m[0][2] - R.m[2][0], R.m[1][0] - R.m[0][1]};
    const double s = axis.norm();
    if (s < 1e-12) {
        if (cos_theta > 0) return {};
        // 180 degrees: the axis is the column of R + I with the largest norm.
        Vec3 best{};
        for (int j = 0; j < 3; ++j) {
            Vec3 col{R.m[0][j] + (j == 0), R.m[1][j] + (j == 1), R.m[2][j] + (j == 2)};
            if (col.norm() > best.norm()) best = col;
        }
        return best.normalized() * theta;
    }
    return axis * (theta / s);
}

constexpr double kPi = 3.14159265358979323846;
inline double radians(double deg) {
    return deg * kPi / 180.0;
}

}  // namespace calbox::sim
