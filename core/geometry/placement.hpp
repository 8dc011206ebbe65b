#pragma once
// The rotation and translation that best carry one planar point set onto another (least
// squares, no scale, no mirror): how an artifact lies on the bed, and what is taken out before
// comparing positions in different frames.
#include <vector>

#include "core/geometry/types.hpp"

namespace calbox::geometry {

struct RigidPlacement {
    double angle_rad = 0;
    Point2 translation_mm;
    Point2 apply(Point2 p) const;
};

// Carries `from[i]` onto `to[i]`; both the same length, at least two points.
RigidPlacement best_rigid_placement(const std::vector<Point2>& from,
                                    const std::vector<Point2>& to);

// The same with a scale (a printed drawing a printer stretched a little): carries `from[i]`
// onto `to[i]` as s R p + t, least squares.
struct SimilarPlacement {
    double angle_rad = 0;
    double scale = 1;
    Point2 translation_mm;
    Point2 apply(Point2 p) const;
};
SimilarPlacement best_similar_placement(const std::vector<Point2>& from,
                                        const std::vector<Point2>& to);

}  // namespace calbox::geometry
