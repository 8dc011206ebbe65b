#include "core/geometry/placement.hpp"

#include <cmath>
#include <stdexcept>

namespace calbox::geometry {

Point2 RigidPlacement::apply(Point2 p) const {
    const double c = std::cos(angle_rad), s = std::sin(angle_rad);
    return {c * p.x - s * p.y + translation_mm.x, s * p.x + c * p.y + translation_mm.y};
}

namespace {

// Both sets' centroids, and about them the sums of cross and dot products (as complex numbers,
// sum(conj(from) to)) and the `from` points' squared norms.
struct PairSums {
    double fx = 0, fy = 0, tx = 0, ty = 0, cross = 0, dot = 0, norm = 0;
};
PairSums pair_sums(const std::vector<Point2>& from,
                   const std::vector<Point2>& to) {
    if (from.size() != to.size() || from.size() < 2)
        throw std::invalid_argument("placement needs two matched point sets");
    PairSums p;
    for (std::size_t i = 0; i < from.size(); ++i)
        p.fx += from[i].x, p.fy += from[i].y, p.tx += to[i].x, p.ty += to[i].y;
    const double n = static_cast<double>(from.size());
    p.fx /= n, p.fy /= n, p.tx /= n, p.ty /= n;
    for (std::size_t i = 0; i < from.size(); ++i) {
        const double ax = from[i].x - p.fx, ay = from[i].y - p.fy, bx = to[i].x - p.tx,
                     by = to[i].y - p.ty;
        p.cross += ax * by - ay * bx;
        p.dot += ax * bx + ay * by;
        p.norm += ax * ax + ay * ay;
    }
    return p;
}

}  // namespace

RigidPlacement best_rigid_placement(const std::vector<Point2>& from,
                                    const std::vector<Point2>& to) {
    const PairSums m = pair_sums(from, to);
    // About the centroids, the best angle is that of the summed cross and dot products.
    RigidPlacement p;
    p.angle_rad = std::atan2(m.cross, m.dot);
    p.translation_mm = {m.tx - (std::cos(p.angle_rad) * m.fx - std::sin(p.angle_rad) * m.fy),
                        m.ty - (std::sin(p.angle_rad) * m.fx + std::cos(p.angle_rad) * m.fy)};
    return p;
}

Point2 SimilarPlacement::apply(Point2 p) const {
    const double c = scale * std::cos(angle_rad), s = scale * std::sin(angle_rad);
    return {c * p.x - s * p.y + translation_mm.x, s * p.x + c * p.y + translation_mm.y};
}

SimilarPlacement best_similar_placement(const std::vector<Point2>& from,
                                        const std::vector<Point2>& to) {
    const PairSums m = pair_sums(from, to);
    if (!(m.norm > 0)) throw std::invalid_argument("placement needs points apart");
    // b = a z about the centroids: a = sum(conj(z) b) / sum(|z|^2).
    SimilarPlacement p;
    p.angle_rad = std::atan2(m.cross, m.dot);
    p.scale = std::hypot(m.cross, m.dot) / m.norm;
    const double ca = p.scale * std::cos(p.angle_rad), sa = p.scale * std::sin(p.angle_rad);
    p.translation_mm = {m.tx - (ca * m.fx - sa * m.fy), m.ty - (sa * m.fx + ca * m.fy)};
    return p;
}

}  // namespace calbox::geometry
