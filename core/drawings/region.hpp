#pragma once
// Regions of the plane as a drawing fills them: a fill rule resolved into a clean polygon set
// (Clipper), clipped to a window (a page, a clip path), inset or outset, and cut by scanlines
// exactly. The SVG reader clips with them; the toolpaths fill with them.
#include <vector>

#include "core/drawings/svg.hpp"
#include "core/geometry/types.hpp"

namespace calbox::drawings {

// One boundary of a resolved region (an outer boundary or a hole).
using Polygon = std::vector<geometry::Point2>;

// The region a set of contours encloses under a fill rule, as outer boundaries and holes that
// do not overlap (open contours closed implicitly).
std::vector<Polygon> resolve_fill(const std::vector<Contour>& contours, FillRule rule);

// The part of a resolved region inside `window` (a resolved region too: a page, a clip path).
std::vector<Polygon> intersect_region(const std::vector<Polygon>& region,
                                      const std::vector<Polygon>& window);

// The pieces of lines (a closed contour with its closing side) inside `window` (a resolved
// region), as open lines.
std::vector<Contour> intersect_lines(const std::vector<Contour>& lines,
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

// Whether the straight move from a to b stays inside a resolved region.
bool segment_inside(const std::vector<Polygon>& region, geometry::Point2 a, geometry::Point2 b);

}  // namespace calbox::drawings
