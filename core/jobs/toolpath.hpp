#pragma once
// Toolpaths for filled and traced shapes: perimeters inset by half the line width so the
// material edge lies on the outline, infill by exact scanline conversion at the configured
// spacing and angle (core/drawings/region.hpp), ordered as a zigzag (boustrophedon) that keeps
// travel short. The delta target's marker cells use the same fill.
#include <cmath>
#include <optional>
#include <vector>

#include "core/drawings/region.hpp"
#include "core/drawings/svg.hpp"
#include "core/geometry/types.hpp"

namespace calbox::jobs {

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

// Perimeters then zigzag infill for a filled shape, starting from `start`.
Toolpath plan_fill(const std::vector<drawings::Contour>& contours, drawings::FillRule rule,
                   const FillSettings& settings, geometry::Point2& start);
// The contours themselves, for shapes with only a stroke.
Toolpath plan_trace(const std::vector<drawings::Contour>& contours, geometry::Point2& start);

void append(Toolpath& to, const Toolpath& from);

}  // namespace calbox::jobs
