#pragma once
// Toolpaths for filled and traced shapes: the fill rule resolved into a clean polygon set
// (Clipper), perimeters inset by half the line width so the material edge lies on the outline,
// infill by exact scanline conversion at the configured spacing and angle, ordered as a zigzag
// (boustrophedon) that keeps travel short. The delta target's marker cells use the same fill.
#include <cmath>
#include <optional>
#include <vector>

#include "core/drawings/svg.hpp"
#include "core/geometry/types.hpp"

namespace calbox::targets {

using Polygon = std::vector<geometry::Point2>;

enum class MoveKind { travel, perimeter, infill, trace };

struct Move {
    geometry::Point2 from, to;
    MoveKind kind = MoveKind::travel;
    double length_mm() const { return std::hypot(to.x - from.x, to.y - from.y); }
};

struct Toolpath {
    std::vector<Move> moves;
    double working_length_mm() const;  // every move but travel
    // Travel between working moves; the approach to the first one depends only on where the
    // machine happens to stand.
    double travel_length_mm() const;
    double length_mm(MoveKind kind) const;
};

struct FillSettings {
    double line_width_mm = 0.45;  // nozzle line, laser spot or cutter width
    double spacing_mm = 0.45;     // between infill lines
    // Infill direction, counter-clockwise from +x; unset: whichever of 0, 45, 90 and 135 degrees
    // travels least for this region.
    std::optional<double> angle_deg;
    int perimeters = 1;
    // Of a line width, into the innermost perimeter. Half a line lets the outermost infill line
    // (up to half a spacing in from the infill region's edge) still meet the perimeter.
    double infill_overlap = 0.5;
};

// The region a set of contours encloses under a fill rule, as outer boundaries and holes that
// do not overlap (open contours closed implicitly).
std::vector<Polygon> resolve_fill(const std::vector<drawings::Contour>& contours,
                                  drawings::FillRule rule);

// The part of a resolved region inside `window` (a resolved region too: a page, a clip path).
std::vector<Polygon> intersect_region(const std::vector<Polygon>& region,
                                      const std::vector<Polygon>& window);

// The pieces of lines (a closed contour with its closing side) inside `window` (a resolved
// region), as open lines.
std::vector<drawings::Contour> intersect_lines(const std::vector<drawings::Contour>& lines,
                                               const std::vector<Polygon>& window);

// Insets (negative) or outsets a resolved region by `distance_mm`, mitred corners.
std::vector<Polygon> offset_region(const std::vector<Polygon>& region, double distance_mm);

// Scanlines across a resolved region at `spacing_mm` and `angle_deg`: each line's intervals
// inside the region, exactly (edge intersections), centred so that the outer lines lie at most
// half a spacing from the region's extremes.
struct ScanSegment {
    geometry::Point2 a, b;
    int line = 0;             // scanline index, in order across the region
    double from = 0, to = 0;  // the interval along the scanline (from < to)
};
std::vector<ScanSegment> scanline_fill(const std::vector<Polygon>& region, double spacing_mm,
                                       double angle_deg);

// Perimeters then zigzag infill for a filled shape, starting from `start`.
Toolpath plan_fill(const std::vector<drawings::Contour>& contours, drawings::FillRule rule,
                   const FillSettings& settings, geometry::Point2& start);
// The contours themselves, for shapes with only a stroke.
Toolpath plan_trace(const std::vector<drawings::Contour>& contours, geometry::Point2& start);

void append(Toolpath& to, const Toolpath& from);

}  // namespace calbox::targets
