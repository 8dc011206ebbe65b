#include "core/solve/placement.hpp"

#include <cmath>
#include <stdexcept>

namespace calbox::solve {

geometry::Point2 RigidPlacement::apply(geometry::Point2 p) const {
    const double c = std::cos(angle_rad), s = std::sin(angle_rad);
    return {c * p.x - s * p.y + translation_mm.x, s * p.x + c * p.y + translation_mm.y};
}

RigidPlacement best_rigid_placement(const std::vector<geometry::Point2>& from,
                                    const std::vector<geometry::Point2>& to) {
    if (from.size() != to.size() || from.size() < 2)
        throw std::invalid_argument("placement needs two matched point sets");
    double fx = 0, fy = 0, tx = 0, ty = 0;
    for (std::size_t i = 0; i < from.size(); ++i)
        fx += from[i].x, fy += from[i].y, tx += to[i].x, ty += to[i].y;
    const double n = static_cast<double>(from.size());
    fx /= n, fy /= n, tx /= n, ty /= n;
    // About the centroids, the best angle is that of the summed cross and dot products.
    double s = 0, c = 0;
    for (std::size_t i = 0; i < from.size(); ++i) {
        const double ax = from[i].x - fx, ay = from[i].y - fy, bx = to[i].x - tx, by = to[i].y - ty;
        s += ax * by - ay * bx;
        c += ax * bx + ay * by;
    }
    RigidPlacement p;
    p.angle_rad = std::atan2(s, c);
    p.translation_mm = {tx - (std::cos(p.angle_rad) * fx - std::sin(p.angle_rad) * fy),
                        ty - (std::sin(p.angle_rad) * fx + std::cos(p.angle_rad) * fy)};
    return p;
}

geometry::Point2 SimilarPlacement::apply(geometry::Point2 p) const {
    const double c = scale * std::cos(angle_rad), s = scale * std::sin(angle_rad);
    return {c * p.x - s * p.y + translation_mm.x, s * p.x + c * p.y + translation_mm.y};
}

SimilarPlacement best_similar_placement(const std::vector<geometry::Point2>& from,
                                        const std::vector<geometry::Point2>& to) {
    if (from.size() != to.size() || from.size() < 2)
        throw std::invalid_argument("placement needs two matched point sets");
    double fx = 0, fy = 0, tx = 0, ty = 0;
    for (std::size_t i = 0; i < from.size(); ++i)
        fx += from[i].x, fy += from[i].y, tx += to[i].x, ty += to[i].y;
    const double n = static_cast<double>(from.size());
    fx /= n, fy /= n, tx /= n, ty /= n;
    // As complex numbers about the centroids, b = a z: a = sum(conj(z) b) / sum(|z|^2).
    double s = 0, c = 0, norm = 0;
    for (std::size_t i = 0; i < from.size(); ++i) {
        const double ax = from[i].x - fx, ay = from[i].y - fy, bx = to[i].x - tx, by = to[i].y - ty;
        s += ax * by - ay * bx;
        c += ax * bx + ay * by;
        norm += ax * ax + ay * ay;
    }
    if (!(norm > 0)) throw std::invalid_argument("placement needs points apart");
    SimilarPlacement p;
    p.angle_rad = std::atan2(s, c);
    p.scale = std::hypot(s, c) / norm;
    const double ca = p.scale * std::cos(p.angle_rad), sa = p.scale * std::sin(p.angle_rad);
    p.translation_mm = {tx - (ca * fx - sa * fy), ty - (sa * fx + ca * fy)};
    return p;
}

}  // namespace calbox::solve
