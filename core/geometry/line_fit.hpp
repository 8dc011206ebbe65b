#pragma once
// Straight lines through measured points: the edges of printed features and of markers.
#include <optional>
#include <vector>

#include "core/geometry/types.hpp"

namespace calbox::geometry {

struct Line {
    Point2 point;      // on the line: the points' mean when fitted
    Point2 direction;  // unit
};

// Total least squares: the line through the mean along the principal axis. At least two points.
Line fit_line(const std::vector<Point2>& points);

// RMS distance of the points from the line.
double line_rms(const Line& line, const std::vector<Point2>& points);

// Empty for parallel lines.
std::optional<Point2> intersect(const Line& a, const Line& b);

}  // namespace calbox::geometry
