#pragma once
// Plain geometric values passed across core's interfaces (OpenCV stays inside the .cpp files).
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

namespace calbox::geometry {

// Node (column, row) of a count x count grid kept row by row, and how many nodes it has.
constexpr std::size_t grid_offset(int column, int row, int count) {
    return static_cast<std::size_t>(row) * static_cast<std::size_t>(count) +
           static_cast<std::size_t>(column);
}
constexpr std::size_t grid_nodes(int count) {
    return static_cast<std::size_t>(count) * static_cast<std::size_t>(count);
}

struct Point2 {
    double x = 0, y = 0;
};

inline double distance(Point2 a, Point2 b) {
    return std::hypot(a.x - b.x, a.y - b.y);
}

struct Point3 {
    double x = 0, y = 0, z = 0;
};

// A rigid transform as OpenCV's rvec (radians, axis times angle) and tvec.
struct RigidPose {
    std::array<double, 3> rvec{0, 0, 0};
    std::array<double, 3> tvec_mm{0, 0, 0};
};

}  // namespace calbox::geometry
