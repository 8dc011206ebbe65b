#include "core/jobs/toolpath.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace calbox::jobs {
using drawings::Contour;
using drawings::FillRule;
using drawings::offset_region;
using drawings::Polygon;
using drawings::resolve_fill;
using drawings::scanline_fill;
using drawings::ScanSegment;
using drawings::segment_inside;
namespace {

using geometry::Point2;

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
// The one segment of scan line `line` that segment `i` overlaps along the scan; nothing where
// it overlaps none or more than one.
std::optional<std::size_t> only_overlap_on(const std::vector<ScanSegment>& segments, std::size_t i,
                                           const std::vector<std::size_t>& line) {
    std::optional<std::size_t> found;
    for (const std::size_t j : line) {
        if (!(segments[i].from < segments[j].to && segments[j].from < segments[i].to)) continue;
        if (found) return std::nullopt;
        found = j;
    }
    return found;
}

std::vector<std::vector<std::size_t>> zigzag_chains(const std::vector<ScanSegment>& segments) {
    std::vector<std::vector<std::size_t>> by_line;
    for (std::size_t i = 0; i < segments.size(); ++i) {
        const auto line = static_cast<std::size_t>(segments[i].line);
        if (by_line.size() <= line) by_line.resize(line + 1);
        by_line[line].push_back(i);
    }
    const auto only_overlap = [&segments](std::size_t i, const std::vector<std::size_t>& line) {
        return only_overlap_on(segments, i, line);
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

}  // namespace calbox::jobs
