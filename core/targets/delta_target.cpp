#include "core/targets/delta_target.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <opencv2/aruco.hpp>

#include "core/geometry/pattern_spec.hpp"

namespace calbox::targets {
using drawings::Contour;
using drawings::FillRule;
using jobs::append;
using jobs::FillSettings;
using jobs::JobError;
using jobs::plan_fill;
using jobs::plan_trace;
using jobs::Toolpath;
namespace {

using geometry::Point2;
constexpr std::array<double, 3> kTowerDeg{210, 330, 90};

Contour square(Point2 c, double half, bool clockwise) {
    Contour q;
    q.closed = true;
    q.points = {{c.x - half, c.y - half},
                {c.x + half, c.y - half},
                {c.x + half, c.y + half},
                {c.x - half, c.y + half}};
    if (clockwise) std::reverse(q.points.begin(), q.points.end());
    return q;
}

// Distance from p to the segment a-b.
double distance_to_segment(Point2 p, Point2 a, Point2 b) {
    const double dx = b.x - a.x, dy = b.y - a.y;
    const double t =
        std::clamp(((p.x - a.x) * dx + (p.y - a.y) * dy) / (dx * dx + dy * dy), 0.0, 1.0);
    return std::hypot(p.x - a.x - t * dx, p.y - a.y - t * dy);
}

}  // namespace

double TargetBar::length_mm() const {
    return std::hypot(ticks_mm[1].x - ticks_mm[0].x, ticks_mm[1].y - ticks_mm[0].y);
}

std::array<Point2, 2> TargetBar::tick_ends_mm(std::size_t which) const {
    const double dx = end_mm.x - start_mm.x, dy = end_mm.y - start_mm.y, len = std::hypot(dx, dy);
    const Point2 n{-dy / len * width_mm / 2, dx / len * width_mm / 2};
    const Point2& t = ticks_mm.at(which);
    return {Point2{t.x + n.x, t.y + n.y}, Point2{t.x - n.x, t.y - n.y}};
}

namespace {

// A marker's squares: its cells, the quiet zone around it and the ring strand's outline.
struct MarkerLayout {
    int cells = 0;  // the marker's bits and its border, per side
    double cell_mm = 0, half_mm = 0, quiet_half_mm = 0, outline_half_mm = 0, outer_half_mm = 0;
};

// Bars along the towers, from the inner radius to the usable edge.
std::vector<TargetBar> tower_bars(const DeltaTargetOptions& o, double w, double usable) {
    std::vector<TargetBar> bars;
    for (int t = 0; t < 3; ++t) {
        const double a = kTowerDeg[static_cast<std::size_t>(t)] * std::numbers::pi / 180;
        TargetBar bar;
        bar.tower = static_cast<char>('A' + t);
        bar.width_mm = o.bar_width_mm;
        const double outer = usable - o.bar_width_mm / 2;
        bar.start_mm = {o.bar_inner_radius_mm * std::cos(a), o.bar_inner_radius_mm * std::sin(a)};
        bar.end_mm = {outer * std::cos(a), outer * std::sin(a)};
        const double tick_inner = o.bar_inner_radius_mm - o.bar_tick_gap_mm - w / 2;
        const double tick_outer = outer + o.bar_tick_gap_mm + w / 2;
        bar.ticks_mm = {Point2{tick_inner * std::cos(a), tick_inner * std::sin(a)},
                        Point2{tick_outer * std::cos(a), tick_outer * std::sin(a)}};
        if (std::hypot(tick_outer + w / 2, o.bar_width_mm / 2) > usable)
            throw JobError("the bars' outer ticks do not fit on the bed");
        bars.push_back(bar);
    }
    return bars;
}

// Markers on a hexagonal grid, clear of the bars and inside the usable disc, nearest the centre
// first so that ids grow outwards; no more than the dictionary has.
std::vector<Point2> marker_centres(const DeltaTargetOptions& o, const std::vector<TargetBar>& bars,
                                   double outer_half, double usable, int dictionary_size) {
    std::vector<Point2> centres;
    const int n = static_cast<int>(usable / o.pitch_mm) + 1;
    for (int j = -n; j <= n; ++j) {
        for (int i = -n; i <= n; ++i) {
            const Point2 c{(i + 0.5 * (j & 1)) * o.pitch_mm, j * o.pitch_mm * std::sqrt(3.0) / 2};
            if (std::hypot(c.x, c.y) + outer_half * std::sqrt(2.0) > usable) continue;
            bool clear = true;
            for (const auto& b : bars) {
                const double d = distance_to_segment(c, {0, 0}, b.end_mm);
                clear = clear && d > outer_half * std::sqrt(2.0) + b.width_mm / 2 + 1;
            }
            if (clear) centres.push_back(c);
        }
    }
    std::stable_sort(centres.begin(), centres.end(), [](Point2 a, Point2 b) {
        return std::hypot(a.x, a.y) < std::hypot(b.x, b.y) - 1e-9;
    });
    if (static_cast<int>(centres.size()) > dictionary_size)
        centres.resize(static_cast<std::size_t>(dictionary_size));
    if (centres.size() < 7)
        throw JobError("only " + std::to_string(centres.size()) + " markers fit on this bed");
    return centres;
}

// The markers in the order they are printed: each the nearest to the one before, from the centre.
std::vector<std::size_t> printing_order(const std::vector<Point2>& centres) {
    std::vector<std::size_t> order;
    std::vector<bool> done(centres.size(), false);
    Point2 at{0, 0};
    for (std::size_t n = 0; n < centres.size(); ++n) {
        std::size_t best = 0;
        double best_d = 1e300;
        for (std::size_t k = 0; k < centres.size(); ++k) {
            const double d = std::hypot(centres[k].x - at.x, centres[k].y - at.y);
            if (!done[k] && d < best_d) best_d = d, best = k;
        }
        done[best] = true;
        order.push_back(best);
        at = centres[best];
    }
    return order;
}

TargetMarker marker_at(int id, Point2 c, const MarkerLayout& l) {
    TargetMarker marker;
    marker.id = id;
    marker.centre_mm = c;
    const double half = l.half_mm, r = l.outline_half_mm;
    marker.corners_mm = {Point2{c.x - half, c.y + half}, Point2{c.x + half, c.y + half},
                         Point2{c.x + half, c.y - half}, Point2{c.x - half, c.y - half}};
    marker.outline_corners_mm = {Point2{c.x - r, c.y + r}, Point2{c.x + r, c.y + r},
                                 Point2{c.x + r, c.y - r}, Point2{c.x - r, c.y - r}};
    marker.outline_half_mm = r;
    return marker;
}

// One marker's toolpath: its white filled, then its ring strand.
void plan_marker(Toolpath& toolpath, const cv::aruco::Dictionary& dictionary, int id, Point2 c,
                 const MarkerLayout& l, const FillSettings& fill, Point2& pen) {
    // White = the quiet-zone square less the black cells (border and zero bits), which wind
    // the other way so that the nonzero rule cuts them out.
    const cv::Mat bits = cv::aruco::Dictionary::getBitsFromByteList(
        dictionary.bytesList.rowRange(id, id + 1), dictionary.markerSize);
    const int cells = l.cells;
    std::vector<Contour> contours{square(c, l.quiet_half_mm, false)};
    for (int r = 0; r < cells; ++r) {
        for (int col = 0; col < cells; ++col) {
            const bool border = r == 0 || col == 0 || r == cells - 1 || col == cells - 1;
            if (!border && bits.at<unsigned char>(r - 1, col - 1) != 0) continue;
            // Row 0 is the marker's top: +y seen from above.
            const Point2 cc{c.x - l.half_mm + (col + 0.5) * l.cell_mm,
                            c.y + l.half_mm - (r + 0.5) * l.cell_mm};
            contours.push_back(square(cc, l.cell_mm / 2, true));
        }
    }
    append(toolpath, plan_fill(contours, FillRule::nonzero, fill, pen));
    // The ring strand, started mid-side: the nozzle's start and stop blobs stay off the
    // corners and off the stretches the centrelines are measured on near them.
    const double outline_half = l.outline_half_mm;
    Contour ring;
    ring.closed = true;
    ring.points = {{c.x, c.y - outline_half},
                   {c.x + outline_half, c.y - outline_half},
                   {c.x + outline_half, c.y + outline_half},
                   {c.x - outline_half, c.y + outline_half},
                   {c.x - outline_half, c.y - outline_half}};
    append(toolpath, plan_trace({ring}, pen));
}

// One bar's toolpath: a filled rectangle whose ends lie exactly at start and end, then its end
// ticks, each drawn from the side the pen is nearer.
void plan_bar(Toolpath& toolpath, const TargetBar& b, const FillSettings& fill, Point2& pen) {
    const double dx = b.end_mm.x - b.start_mm.x, dy = b.end_mm.y - b.start_mm.y,
                 len = std::hypot(dx, dy);
    const Point2 n{-dy / len * b.width_mm / 2, dx / len * b.width_mm / 2};
    Contour r;
    r.closed = true;
    r.points = {{b.start_mm.x + n.x, b.start_mm.y + n.y},
                {b.start_mm.x - n.x, b.start_mm.y - n.y},
                {b.end_mm.x - n.x, b.end_mm.y - n.y},
                {b.end_mm.x + n.x, b.end_mm.y + n.y}};
    append(toolpath, plan_fill({r}, FillRule::nonzero, fill, pen));
    for (std::size_t k = 0; k < b.ticks_mm.size(); ++k) {
        const auto ends = b.tick_ends_mm(k);
        Contour line;
        line.closed = false;
        line.points = {ends[0], ends[1]};
        if (std::hypot(pen.x - line.points[1].x, pen.y - line.points[1].y) <
            std::hypot(pen.x - line.points[0].x, pen.y - line.points[0].y))
            std::swap(line.points[0], line.points[1]);
        append(toolpath, plan_trace({line}, pen));
    }
}

// The fingerprint ties measurements to this exact layout on this exact machine.
std::string layout_fingerprint(const models::MachineFile& machine, const DeltaTargetOptions& o,
                               const std::vector<TargetMarker>& markers) {
    std::string canonical = models::fingerprint(machine) + "|" + o.dictionary;
    char b[64];
    for (const auto& m : markers) {
        std::snprintf(b, sizeof b, "|%d:%.4f,%.4f", m.id, m.centre_mm.x, m.centre_mm.y);
        canonical += b;
    }
    std::snprintf(b, sizeof b, "|%.4f|%.4f|%d|%.4f|ticks %.4f", o.marker_mm, o.bar_width_mm,
                  o.layers, o.outline_gap_mm, o.bar_tick_gap_mm);
    canonical += b;
    return models::digest(canonical);
}

}  // namespace

DeltaTarget make_delta_target(const models::MachineFile& machine, const DeltaTargetOptions& o) {
    if (!machine.is_delta())
        throw JobError("the delta target is for delta printers, not a " + machine.kind);
    DeltaTarget target;
    const double w = machine.line_width_mm;
    const auto dictionary =
        cv::aruco::getPredefinedDictionary(geometry::aruco_dictionary_id(o.dictionary));
    MarkerLayout layout;
    layout.cells = dictionary->markerSize + 2;
    layout.cell_mm = o.marker_mm / layout.cells;
    if (layout.cell_mm < 3 * w)
        throw JobError("marker cells of " + std::to_string(layout.cell_mm) +
                       " mm are too small for a " + std::to_string(w) + " mm line");
    layout.half_mm = o.marker_mm / 2;
    layout.quiet_half_mm = o.marker_mm / 2 + layout.cell_mm;  // the white margin around it
    layout.outline_half_mm = layout.quiet_half_mm + o.outline_gap_mm + w / 2;
    layout.outer_half_mm = layout.outline_half_mm + w / 2;  // the ring strand's outer edge
    const double usable = machine.bed_radius_mm - 5;        // clear of the clips and the edge
    if (usable < 30) throw JobError("the bed is too small for the delta target");

    target.bars = tower_bars(o, w, usable);
    const std::vector<Point2> centres =
        marker_centres(o, target.bars, layout.outer_half_mm, usable, dictionary->bytesList.rows);
    for (std::size_t k = 0; k < centres.size(); ++k)
        target.markers.push_back(marker_at(static_cast<int>(k), centres[k], layout));

    FillSettings fill;
    fill.line_width_mm = w;
    fill.spacing_mm = w;
    fill.perimeters = 1;
    Point2 pen{0, 0};
    for (const std::size_t k : printing_order(centres))
        plan_marker(target.job.toolpath, *dictionary, static_cast<int>(k), centres[k], layout, fill,
                    pen);
    for (const auto& b : target.bars) plan_bar(target.job.toolpath, b, fill, pen);
    target.job.line_width_mm = w;
    target.job.spacing_mm = w;
    target.job.feed_mm_s = machine.feed_mm_s;
    target.job.layers = o.layers;
    target.job.min_x = target.job.min_y = -usable;
    target.job.max_x = target.job.max_y = usable;
    target.top_height_mm = o.layers * machine.layer_height_mm;
    target.marker_half_mm = layout.half_mm;
    target.ring_gap_mm = o.outline_gap_mm;
    target.strand_width_mm = w;
    target.strand_section_mm2 = w * machine.layer_height_mm;
    target.fingerprint = layout_fingerprint(machine, o, target.markers);
    return target;
}

}  // namespace calbox::targets
