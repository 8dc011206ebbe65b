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

// The standard uncertainty of a fitted line's position across it at `at`, from the points' own
// scatter about it: s^2 (1/n + t^2 / S_tt), t measured along the line from the points' mean.
// `independent_share` of the points count as independent (samples closer than the noise's
// reach share it). Zero for two points or fewer (no scatter to judge from).
double line_sigma_at(const Line& line, const std::vector<Point2>& points, Point2 at,
                     double independent_share = 1);

// Empty for parallel lines.
std::optional<Point2> intersect(const Line& a, const Line& b);

}  // namespace calbox::geometry
