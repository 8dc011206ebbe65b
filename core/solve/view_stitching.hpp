#pragma once
// Overlapping photos of one grid put in one frame: each view's turn and shift against the first
// (whose frame it is), fitted by least squares so that a point two views share is seen at one
// place, and every point then where its views place it.
#include <optional>
#include <stdexcept>
#include <vector>

#include "core/geometry/types.hpp"

namespace calbox::solve {

class StitchError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct ViewStitch {
    std::vector<double> angle_rad;              // per view; the first's 0
    std::vector<geometry::Point2> shift_mm;     // per view; the first's as it started
    std::vector<geometry::Point2> position_mm;  // per point: its views' places averaged
    // Where view `v` puts a point it saw at `seen` in its own frame.
    geometry::Point2 place(std::size_t v, geometry::Point2 seen) const;
};

// `seen[v][h]`: where view v saw point h in its own frame, if it did; `start_shift_mm[v]`: each
// view's shift to start from (the first's kept). The views' turns and shifts and the shared
// points' places by Gauss-Newton (six steps at most, until no shift moves by 1e-9 mm); a point
// seen once follows its view. Throws StitchError when the shared points do not fix the views.
ViewStitch stitch_views(const std::vector<std::vector<std::optional<geometry::Point2>>>& seen,
                        std::vector<geometry::Point2> start_shift_mm);

}  // namespace calbox::solve
