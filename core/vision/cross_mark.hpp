#pragma once
// A printed cross's centre (print and cut's third kind of mark): where its two bars' centre lines
// cross. Each bar is measured across at stations along both its arms, clear of the crossing and
// the tips, as the centroid of its darkness on the profile (bilinear samples, the edge kernel's
// sampling); a line is fitted to each bar's points and the two intersected. A blob centroid
// would need the whole cross inside a round window and an even print; the lines need neither.
#include <optional>

#include "core/geometry/types.hpp"
#include "core/image_view.hpp"

namespace calbox::vision {

struct CrossCentre {
    geometry::Point2 centre_px;
    double sigma_px = 0;  // each coordinate's standard uncertainty, from the bars' scatter
    double turn_deg = 0;  // the first bar against the image's x, 0 to 90
    int profiles = 0;     // the stations measured on both bars
};

// `rough_px` within a bar's width of the centre (a blob's centroid); `span_px` tip to tip,
// `bar_px` a bar's width, both in the photo. Empty when a bar does not show on enough stations
// (a cross cut by the image's edge, a smudge, not a cross).
std::optional<CrossCentre> measure_cross(const GrayView& image, geometry::Point2 rough_px,
                                         double span_px, double bar_px);

}  // namespace calbox::vision
