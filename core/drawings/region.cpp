#include "core/drawings/region.hpp"

#include <algorithm>
#include <clipper.hpp>
#include <cmath>
#include <limits>
#include <numbers>

namespace calbox::drawings {
namespace {

using geometry::Point2;
constexpr double kScale = 1e5;  // Clipper works in integers: 10 nm units

ClipperLib::Path to_clipper(const Polygon& polygon) {
    ClipperLib::Path path;
    path.reserve(polygon.size());
    for (const auto& p : polygon) {
        path.emplace_back(static_cast<ClipperLib::cInt>(std::llround(p.x * kScale)),
                          static_cast<ClipperLib::cInt>(std::llround(p.y * kScale)));
    }
    return path;
}

// Paths of at least `min_points` (a polygon's 3; an open line's 2).
std::vector<Polygon> from_clipper(const ClipperLib::Paths& paths, std::size_t min_points = 3) {
    std::vector<Polygon> out;
    for (const auto& path : paths) {
        if (path.size() < min_points) continue;
        Polygon polygon;
        for (const auto& p : path)
            polygon.push_back(
                {static_cast<double>(p.X) / kScale, static_cast<double>(p.Y) / kScale});
        out.push_back(std::move(polygon));
    }
    return out;
}

bool point_inside(const std::vector<Polygon>& region, Point2 p) {
    bool inside = false;  // crossing number over every boundary: the region is even-odd clean
    for (const auto& polygon : region) {
        for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
            const Point2 &a = polygon[i], &b = polygon[j];
            if ((a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x)
                inside = !inside;
        }
    }
    return inside;
}

bool segments_cross(Point2 p, Point2 q, Point2 a, Point2 b) {
    const auto side = [](Point2 o, Point2 u, Point2 v) {
        return (u.x - o.x) * (v.y - o.y) - (u.y - o.y) * (v.x - o.x);
    };
    const double d1 = side(a, b, p), d2 = side(a, b, q), d3 = side(p, q, a), d4 = side(p, q, b);
    return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
}

}  // namespace

bool segment_inside(const std::vector<Polygon>& region, Point2 a, Point2 b) {
    if (!point_inside(region, a) || !point_inside(region, b)) return false;
    for (const auto& polygon : region)
        for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++)
            if (segments_cross(a, b, polygon[i], polygon[j])) return false;
    return true;
}

std::vector<Polygon> resolve_fill(const std::vector<Contour>& contours, FillRule rule) {
    ClipperLib::Clipper clipper;
    for (const auto& c : contours) {
        if (c.points.size() < 3) continue;
        clipper.AddPath(to_clipper(c.points), ClipperLib::ptSubject, true);
    }
    ClipperLib::Paths solution;
    const auto type = rule == FillRule::evenodd ? ClipperLib::pftEvenOdd : ClipperLib::pftNonZero;
    clipper.Execute(ClipperLib::ctUnion, solution, type, type);
    return from_clipper(solution);
}

std::vector<Polygon> intersect_region(const std::vector<Polygon>& region,
                                      const std::vector<Polygon>& window) {
    ClipperLib::Clipper clipper;
    for (const auto& p : region) clipper.AddPath(to_clipper(p), ClipperLib::ptSubject, true);
    for (const auto& p : window) clipper.AddPath(to_clipper(p), ClipperLib::ptClip, true);
    ClipperLib::Paths solution;
    clipper.Execute(ClipperLib::ctIntersection, solution, ClipperLib::pftNonZero,
                    ClipperLib::pftNonZero);
    return from_clipper(solution);
}

std::vector<Contour> intersect_lines(const std::vector<Contour>& lines,
                                     const std::vector<Polygon>& window) {
    ClipperLib::Clipper clipper;
    for (const auto& c : lines) {
        Polygon points = c.points;
        if (c.closed && !points.empty()) points.push_back(points.front());
        if (points.size() >= 2) clipper.AddPath(to_clipper(points), ClipperLib::ptSubject, false);
    }
    for (const auto& p : window) clipper.AddPath(to_clipper(p), ClipperLib::ptClip, true);
    ClipperLib::PolyTree tree;
    clipper.Execute(ClipperLib::ctIntersection, tree, ClipperLib::pftNonZero,
                    ClipperLib::pftNonZero);
    ClipperLib::Paths open;
    ClipperLib::OpenPathsFromPolyTree(tree, open);
    std::vector<Contour> out;
    for (auto& piece : from_clipper(open, 2)) out.push_back({std::move(piece), false});
    return out;
}

std::vector<Polygon> offset_region(const std::vector<Polygon>& region, double distance_mm) {
    ClipperLib::Paths paths;
    for (const auto& p : region) paths.push_back(to_clipper(p));
    ClipperLib::ClipperOffset offset(2.0, 0.25 * kScale * 0.001);
    offset.AddPaths(paths, ClipperLib::jtMiter, ClipperLib::etClosedPolygon);
    ClipperLib::Paths solution;
    offset.Execute(solution, distance_mm * kScale);
    return from_clipper(solution);
}

std::vector<ScanSegment> scanline_fill(const std::vector<Polygon>& region, double spacing_mm,
                                       double angle_deg) {
    std::vector<ScanSegment> out;
    if (region.empty() || !(spacing_mm > 0)) return out;
    // Rotate the region so the scanlines run along x.
    const double a = angle_deg * std::numbers::pi / 180, ca = std::cos(a), sa = std::sin(a);
    std::vector<Polygon> rotated;
    double ymin = std::numeric_limits<double>::infinity(), ymax = -ymin;
    for (const auto& polygon : region) {
        Polygon r;
        for (const auto& p : polygon) {
            r.push_back({ca * p.x + sa * p.y, -sa * p.x + ca * p.y});
            ymin = std::min(ymin, r.back().y);
            ymax = std::max(ymax, r.back().y);
        }
        rotated.push_back(std::move(r));
    }
    const int count = static_cast<int>(std::floor((ymax - ymin) / spacing_mm)) + 1;
    const double first = (ymin + ymax) / 2 - (count - 1) * spacing_mm / 2;
    std::vector<double> xs;
    for (int k = 0; k < count; ++k) {
        const double y = first + k * spacing_mm;
        xs.clear();
        for (const auto& polygon : rotated) {
            for (std::size_t i = 0; i < polygon.size(); ++i) {
                const Point2& p = polygon[i];
                const Point2& q = polygon[(i + 1) % polygon.size()];
                // Half-open rule: a vertex on the line counts once.
                if ((p.y <= y && y < q.y) || (q.y <= y && y < p.y))
                    xs.push_back(p.x + (y - p.y) * (q.x - p.x) / (q.y - p.y));
            }
        }
        std::sort(xs.begin(), xs.end());
        // The resolved region has no overlaps, so crossings pair up inside/outside.
        for (std::size_t i = 0; i + 1 < xs.size(); i += 2) {
            if (xs[i + 1] - xs[i] < 1e-9) continue;
            const Point2 l{xs[i], y}, r{xs[i + 1], y};
            out.push_back({{ca * l.x - sa * l.y, sa * l.x + ca * l.y},
                           {ca * r.x - sa * r.y, sa * r.x + ca * r.y},
                           k,
                           l.x,
                           r.x});
        }
    }
    return out;
}

}  // namespace calbox::drawings
