#include "core/targets/toolpath.hpp"

#include <algorithm>
#include <clipper.hpp>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

namespace calbox::targets {
using drawings::Contour;
using drawings::FillRule;
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

double distance2(Point2 a, Point2 b) {
    return (a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y);
}

void travel_to(Toolpath& path, Point2& pen, Point2 to) {
    if (distance2(pen, to) > 1e-18) path.moves.push_back({pen, to, MoveKind::travel});
    pen = to;
}

void draw_to(Toolpath& path, Point2& pen, Point2 to, MoveKind kind) {
    if (distance2(pen, to) > 1e-18) path.moves.push_back({pen, to, kind});
    pen = to;
}

// Closed loops visited nearest first, each entered at its vertex nearest the pen.
void visit_loops(Toolpath& path, Point2& pen, std::vector<Polygon> loops, MoveKind kind) {
    while (!loops.empty()) {
        std::size_t best_loop = 0, best_vertex = 0;
        double best = std::numeric_limits<double>::infinity();
        for (std::size_t l = 0; l < loops.size(); ++l) {
            for (std::size_t v = 0; v < loops[l].size(); ++v) {
                const double d = distance2(pen, loops[l][v]);
                if (d < best) best = d, best_loop = l, best_vertex = v;
            }
        }
        const Polygon& loop = loops[best_loop];
        travel_to(path, pen, loop[best_vertex]);
        for (std::size_t k = 1; k <= loop.size(); ++k)
            draw_to(path, pen, loop[(best_vertex + k) % loop.size()], kind);
        loops.erase(loops.begin() + static_cast<std::ptrdiff_t>(best_loop));
    }
}

// Runs of segments on consecutive scanlines that continue one another (each overlaps only the
// other across the gap): one lobe of the region, filled as one zigzag.
std::vector<std::vector<std::size_t>> zigzag_chains(const std::vector<ScanSegment>& segments) {
    std::vector<std::vector<std::size_t>> by_line;
    for (std::size_t i = 0; i < segments.size(); ++i) {
        const auto line = static_cast<std::size_t>(segments[i].line);
        if (by_line.size() <= line) by_line.resize(line + 1);
        by_line[line].push_back(i);
    }
    const auto overlaps = [&](std::size_t i, std::size_t j) {
        return segments[i].from < segments[j].to && segments[j].from < segments[i].to;
    };
    const auto only_overlap =
        [&](std::size_t i, const std::vector<std::size_t>& line) -> std::optional<std::size_t> {
        std::optional<std::size_t> found;
        for (const std::size_t j : line) {
            if (!overlaps(i, j)) continue;
            if (found) return std::nullopt;
            found = j;
        }
        return found;
    };
    std::vector<bool> placed(segments.size(), false);
    std::vector<std::vector<std::size_t>> chains;
    for (std::size_t line = 0; line < by_line.size(); ++line) {
        for (const std::size_t first : by_line[line]) {
            if (placed[first]) continue;
            std::vector<std::size_t> chain{first};
            placed[first] = true;
            for (std::size_t k = line; k + 1 < by_line.size(); ++k) {
                const auto next = only_overlap(chain.back(), by_line[k + 1]);
                if (!next || placed[*next] || only_overlap(*next, by_line[k]) != chain.back())
                    break;
                chain.push_back(*next);
                placed[*next] = true;
            }
            chains.push_back(std::move(chain));
        }
    }
    return chains;
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

// Whether the straight move from a to b stays inside the region.
bool segment_inside(const std::vector<Polygon>& region, Point2 a, Point2 b) {
    if (!point_inside(region, a) || !point_inside(region, b)) return false;
    for (const auto& polygon : region)
        for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++)
            if (segments_cross(a, b, polygon[i], polygon[j])) return false;
    return true;
}

// Chains nearest first, each entered at whichever of its four corner ends is nearest the pen,
// then walked line by line, reversing direction on each (boustrophedon). Within a chain the
// short link from one line's end to the next line's start is part of the zigzag and is worked
// like the lines (it runs along the edge of the infill, over the perimeter's overlap).
void order_infill(Toolpath& path, Point2& pen, const std::vector<ScanSegment>& segments,
                  double longest_link_mm, const std::vector<Polygon>& link_region) {
    auto chains = zigzag_chains(segments);
    while (!chains.empty()) {
        std::size_t best = 0;
        bool from_back = false, reversed = false;
        double best_d = std::numeric_limits<double>::infinity();
        for (std::size_t c = 0; c < chains.size(); ++c) {
            for (const bool back : {false, true}) {
                const auto& seg = segments[back ? chains[c].back() : chains[c].front()];
                for (const bool rev : {false, true}) {
                    const double d = distance2(pen, rev ? seg.b : seg.a);
                    if (d < best_d) best_d = d, best = c, from_back = back, reversed = rev;
                }
            }
        }
        auto chain = std::move(chains[best]);
        chains.erase(chains.begin() + static_cast<std::ptrdiff_t>(best));
        if (from_back) std::reverse(chain.begin(), chain.end());
        bool first = true;
        for (const std::size_t i : chain) {
            const auto& seg = segments[i];
            const Point2 entry = reversed ? seg.b : seg.a;
            // A link is worked where it stays on the material (inside the perimeter's centreline),
            // so it never marks a hole; beyond a few millimetres it is travel all the same.
            if (!first && distance2(pen, entry) <= longest_link_mm * longest_link_mm &&
                segment_inside(link_region, pen, entry)) {
                draw_to(path, pen, entry, MoveKind::infill);
            } else {
                travel_to(path, pen, entry);
            }
            first = false;
            draw_to(path, pen, reversed ? seg.a : seg.b, MoveKind::infill);
            reversed = !reversed;
        }
    }
}

}  // namespace

double Toolpath::length_mm(MoveKind kind) const {
    double sum = 0;
    for (const auto& m : moves)
        if (m.kind == kind) sum += m.length_mm();
    return sum;
}

double Toolpath::working_length_mm() const {
    double sum = 0;
    for (const auto& m : moves)
        if (m.kind != MoveKind::travel) sum += m.length_mm();
    return sum;
}

double Toolpath::travel_length_mm() const {
    double sum = 0;
    bool started = false;
    for (const auto& m : moves) {
        if (m.kind != MoveKind::travel) {
            started = true;
        } else if (started) {
            sum += m.length_mm();
        }
    }
    return sum;
}

void append(Toolpath& to, const Toolpath& from) {
    to.moves.insert(to.moves.end(), from.moves.begin(), from.moves.end());
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

Toolpath plan_fill(const std::vector<Contour>& contours, FillRule rule, const FillSettings& s,
                   Point2& pen) {
    Toolpath path;
    const auto region = resolve_fill(contours, rule);
    const double w = s.line_width_mm;
    for (int i = 0; i < s.perimeters; ++i)
        visit_loops(path, pen, offset_region(region, -(w / 2 + i * w)), MoveKind::perimeter);
    // Infill line centres keep half a line from the innermost perimeter's inner edge, less the
    // overlap.
    const double inset = s.perimeters * w + w / 2 - s.infill_overlap * w;
    const auto infill_region = offset_region(region, -inset);
    const auto link_region = offset_region(region, -w / 2);
    const auto infill_at = [&](double angle_deg, Point2 from) {
        Toolpath infill;
        order_infill(infill, from, scanline_fill(infill_region, s.spacing_mm, angle_deg),
                     std::max(10.0, 3 * s.spacing_mm), link_region);
        return std::make_pair(infill, from);
    };
    auto best = infill_at(s.angle_deg.value_or(0), pen);
    if (!s.angle_deg) {
        for (const double angle : {45.0, 90.0, 135.0}) {
            auto candidate = infill_at(angle, pen);
            // Compare travel including the way in from the perimeter.
            if (candidate.first.length_mm(MoveKind::travel) <
                best.first.length_mm(MoveKind::travel) - 1e-9)
                best = std::move(candidate);
        }
    }
    append(path, best.first);
    pen = best.second;
    return path;
}

Toolpath plan_trace(const std::vector<Contour>& contours, Point2& pen) {
    Toolpath path;
    for (const auto& c : contours) {
        if (c.points.empty()) continue;
        travel_to(path, pen, c.points.front());
        for (std::size_t i = 1; i < c.points.size(); ++i)
            draw_to(path, pen, c.points[i], MoveKind::trace);
        if (c.closed) draw_to(path, pen, c.points.front(), MoveKind::trace);
    }
    return path;
}

}  // namespace calbox::targets
