#pragma once
// What measure found, drawn on its first photo (`calbox measure --overlay` and each cycle's record,
// cycle-NNNN-overlay.png): the grid modes' common drawing here, each mode's own overlay beside its
// adapter (firmware/modes/). PNG bytes, so that OpenCV stays out of this header.
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/models/machine_file.hpp"
#include "core/image_view.hpp"

namespace calbox::firmware {

// A grid mode's overlay (galvo_mode, planar_mode: each mode draws its own): the marks found
// (green; those `labelled` says, with their column,row) and the extra blobs (orange, twice the
// size), all on the sheet's surface at height z_mm.
struct GridMark {
    geometry::Point2 measured_mm;
    int column = 0, row = 0;
    bool labelled = false;
};
struct GridMarkStyle {
    int radius_divisor;         // the mark's radius: the picture's width / this (at least 4 px)
    int label_offset_radii;     // the label's start, right of the mark, in radii
    double font_scale_divisor;  // the label's scale: the picture's width / this
};
std::string grid_overlay_png(const vision::GrayView& photo, const std::vector<GridMark>& marks,
                             const std::vector<geometry::Point2>& extra_mm, double z_mm,
                             const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                             const GridMarkStyle& style);

// The error field on a plain map of the machine's frame (x right, y up): each point's error as
// an arrow, magnified by a round factor that makes the largest about a twelfth of the map, with
// the factor, the largest error and a scale bar printed. Each cycle's record
// (cycle-NNNN-error-field.png), for the page. Throws std::invalid_argument without a point.
struct FieldArrow {
    geometry::Point2 at_mm, error_mm;
};
std::string error_field_png(const std::vector<FieldArrow>& arrows, const std::string& title);

}  // namespace calbox::firmware
