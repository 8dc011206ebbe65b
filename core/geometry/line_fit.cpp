#include "core/geometry/line_fit.hpp"

#include <algorithm>
#include <cmath>

namespace calbox::geometry {

Line fit_line(const std::vector<Point2>& points) {
    double mx = 0, my = 0;
    for (const auto& p : points) mx += p.x, my += p.y;
    mx /= static_cast<double>(points.size());
    my /= static_cast<double>(points.size());
    double sxx = 0, sxy = 0, syy = 0;
    for (const auto& p : points) {
        sxx += (p.x - mx) * (p.x - mx);
        sxy += (p.x - mx) * (p.y - my);
        syy += (p.y - my) * (p.y - my);
    }
    const double angle = 0.5 * std::atan2(2 * sxy, sxx - syy);
    return {{mx, my}, {std::cos(angle), std::sin(angle)}};
}

double line_rms(const Line& line, const std::vector<Point2>& points) {
    if (points.empty()) return 0;
    double sum = 0;
    for (const auto& p : points) {
        const double d =
            (p.x - line.point.x) * line.direction.y - (p.y - line.point.y) * line.direction.x;
        sum += d * d;
    }
    return std::sqrt(sum / static_cast<double>(points.size()));
}

double line_sigma_at(const Line& line, const std::vector<Point2>& points, Point2 at,
                     double independent_share) {
    const auto n = static_cast<double>(points.size());
    if (points.size() <= 2) return 0;
    double along = 0, across = 0;
    for (const auto& p : points) {
        const double dx = p.x - line.point.x, dy = p.y - line.point.y;
        const double t = dx * line.direction.x + dy * line.direction.y;
        const double d = dx * line.direction.y - dy * line.direction.x;
        along += t * t;
        across += d * d;
    }
    const double scatter = across / (n - 2);
    const double t_at =
        (at.x - line.point.x) * line.direction.x + (at.y - line.point.y) * line.direction.y;
    const double share = std::clamp(independent_share, 1e-3, 1.0);
    return std::sqrt(scatter * (1 / (n * share) + (along > 0 ? t_at * t_at / (along * share) : 0)));
}

std::optional<Point2> intersect(const Line& a, const Line& b) {
    const double det = a.direction.x * b.direction.y - a.direction.y * b.direction.x;
    if (std::abs(det) < 1e-9) return std::nullopt;
    const double dx = b.point.x - a.point.x, dy = b.point.y - a.point.y;
    const double t = (dx * b.direction.y - dy * b.direction.x) / det;
    return Point2{a.point.x + t * a.direction.x, a.point.y + t * a.direction.y};
}

}  // namespace calbox::geometry
