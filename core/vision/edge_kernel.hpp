#pragma once
// Per-pixel measurement kernels in integer arithmetic: bilinear sampling along a line and the
// location of a step edge on the sampled profile. Positions are fixed-point: Q16 is 1/65536 of
// a pixel (or of a profile sample); sampled values are Q8, 1/256 of a grey level. The double
// versions are the references the integer ones are tested against.
#include <cstdint>
#include <optional>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/vision/image_view.hpp"

namespace calbox::vision {

constexpr std::int64_t kQ16 = 65536;

inline std::int64_t to_q16(double v) {
    return static_cast<std::int64_t>(v * kQ16 + (v >= 0 ? 0.5 : -0.5));
}
inline double from_q16(std::int64_t v) {
    return static_cast<double>(v) / kQ16;
}

// Samples `count` points from (x0, y0) in steps of (dx, dy), all in Q16 pixels, bilinearly, into
// `out` (Q8 grey levels). Returns false, leaving `out` unspecified, if a sample falls outside the
// image (a bilinear sample needs its 2x2 neighbourhood).
bool sample_profile_q8(const GrayView& image, std::int64_t x0_q16, std::int64_t y0_q16,
                       std::int64_t dx_q16, std::int64_t dy_q16, int count, std::int32_t* out);

// The centre of a step edge on a profile: the centroid of the gradient that runs in the
// expected direction (rising: dark to bright), above a fifth of its peak so that noise in the
// flat parts does not pull it. In samples from the profile's start, Q16; empty without an edge.
std::optional<std::int64_t> step_edge_q16(const std::int32_t* profile_q8, int count, bool rising);

// The step edge on the straight segment from `from` to `to` (pixels), sampled every 1/8 pixel:
// where along it the image steps up (rising) or down, as a pixel position. Empty when the
// segment leaves the image or shows no such step.
std::optional<geometry::Point2> step_edge_on_segment(const GrayView& image, geometry::Point2 from,
                                                     geometry::Point2 to, bool rising);

// Double-precision references of the same computations.
double sample_reference(const GrayView& image, double x, double y);
std::optional<double> step_edge_reference(const std::vector<double>& profile, bool rising);

}  // namespace calbox::vision
