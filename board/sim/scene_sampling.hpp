#pragma once
// Inside the twin's scenes (board/sim/scenes.cpp, board_scenes.cpp): the albedos of the paper
// and the ink, and a pixel's footprint sampled over sub-squares where an edge crosses it.
#include <algorithm>
#include <cmath>

#include "board/sim/scenes.hpp"

namespace calbox::sim::scene_sampling {

inline constexpr double kBlack = 0.05, kWhite = 0.90, kBackground = 0.35;

struct Extent {
    double x_mm, y_mm;
};
inline Extent half_extent(const Footprint& f) {
    return {0.5 * (std::abs(f.jacobian[0][0]) + std::abs(f.jacobian[0][1])),
            0.5 * (std::abs(f.jacobian[1][0]) + std::abs(f.jacobian[1][1]))};
}

inline Vec2 offset_in_pixel(const Footprint& f, double du, double dv) {
    return {f.centre_mm.x + f.jacobian[0][0] * du + f.jacobian[0][1] * dv,
            f.centre_mm.y + f.jacobian[1][0] * du + f.jacobian[1][1] * dv};
}

// Calls fn(point, subdivisions) at the centre of each of s x s sub-squares of the pixel and
// returns the mean of what it gives.
template <class Fn>
double average_over_subpixels(const Footprint& f, int s, Fn&& fn) {
    double sum = 0;
    for (int iy = 0; iy < s; ++iy)
        for (int ix = 0; ix < s; ++ix)
            sum += fn(offset_in_pixel(f, (ix + 0.5) / s - 0.5, (iy + 0.5) / s - 0.5));
    return sum / (s * s);
}

// A pattern of square cells aligned with the plane's axes; cell (i, j) spans
// [origin + i * pitch, origin + (i + 1) * pitch] in x, likewise j in y.
template <class CellAlbedo>
double grid_albedo(const Footprint& f, Vec2 origin, double pitch, int s, CellAlbedo&& cell) {
    const Extent e = half_extent(f);
    const double gx = (f.centre_mm.x - origin.x) / pitch, gy = (f.centre_mm.y - origin.y) / pitch;
    const double ix = std::floor(gx), iy = std::floor(gy);
    const bool near_x = std::min(gx - ix, ix + 1 - gx) * pitch < e.x_mm;
    const bool near_y = std::min(gy - iy, iy + 1 - gy) * pitch < e.y_mm;
    if (!near_x && !near_y) return cell(static_cast<int>(ix), static_cast<int>(iy));
    return average_over_subpixels(f, s, [&](Vec2 q) {
        const int kx = static_cast<int>(std::lround((q.x - origin.x) / pitch));
        const int ky = static_cast<int>(std::lround((q.y - origin.y) / pitch));
        // Fractions of the sub-square beyond the nearest vertical and horizontal lines.
        const double cx = inside_fraction(origin.x + kx * pitch - q.x, {-1, 0}, f.jacobian, s);
        const double cy = inside_fraction(origin.y + ky * pitch - q.y, {0, -1}, f.jacobian, s);
        return (1 - cx) * (1 - cy) * cell(kx - 1, ky - 1) + cx * (1 - cy) * cell(kx, ky - 1) +
               (1 - cx) * cy * cell(kx - 1, ky) + cx * cy * cell(kx, ky);
    });
}

}  // namespace calbox::sim::scene_sampling
