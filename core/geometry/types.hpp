#pragma once
// Plain geometric values passed across core's interfaces (OpenCV stays inside the .cpp files).
#include <array>
#include <vector>

namespace calbox::geometry {

struct Point2 {
    double x = 0, y = 0;
};

struct Point3 {
    double x = 0, y = 0, z = 0;
};

// A rigid transform as OpenCV's rvec (radians, axis times angle) and tvec.
struct RigidPose {
    std::array<double, 3> rvec{0, 0, 0};
    std::array<double, 3> tvec_mm{0, 0, 0};
};

}  // namespace calbox::geometry
