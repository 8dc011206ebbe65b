#pragma once
// Per-pixel measurement kernels in integer arithmetic: bilinear sampling along a line and the
// location of a step edge on the sampled profile. Positions are fixed-point: Q16 is 1/65536 of
// a pixel (or of a profile sample); sampled values are Q8, 1/256 of a grey level. The double
// versions are the references the integer ones are tested against.
#include <cstdint>
#include <optional>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/image_view.hpp"

namespace calbox::vision {

constexpr std::int64_t kQ16 = 65536;

inline std::int64_t to_q16(double v) {
    return static_cast<std::int64_t>(v * kQ16 + (v >= 0 ? 0.5 : -0.5));
}
inline double from_q16(std::int64_t v) {
    return static_cast<double>(v) / kQ16;
}

// The edge kernel's two limits, with why they are what they are.
struct EdgeKernelSettings {
    // Gradients below this share of the profile's steepest are left out of the centroid: the
    // flat parts' noise (2-3 counts a sample) would otherwise pull the edge towards the
    // profile's middle; a fifth keeps a blurred edge's shoulders, which carry its position.
    int gradient_floor_divisor = 5;
    // Profiles are sampled every 1/8 pixel along the segment: bilinear interpolation between
    // pixels then places a sharp edge within 1/100 pixel, and a segment of a few pixels gives
    // the centroid enough samples.
    double sample_step_px = 0.125;
};

// Samples `count` points from (x0, y0) in steps of (dx, dy), all in Q16 pixels, bilinearly, into
// `out` (Q8 grey levels). Returns false, leaving `out` unspecified, if a sample falls outside the
// image (a bilinear sample needs its 2x2 neighbourhood).
bool sample_profile_q8(const GrayView& image, std::int64_t x0_q16, std::int64_t y0_q16,
                       std::int64_t dx_q16, std::int64_t dy_q16, int count, std::int32_t* out);

// The centre of a step edge on a profile: the centroid of the gradient that runs in the
// expected direction (rising: dark to bright) over the steepest step's own lobe, above a share
// of its peak (the settings') so that noise in the flat parts does not pull it; a second,
// weaker step elsewhere on the profile is left out. In samples from the profile's start, Q16;
// empty without an edge.
std::optional<std::int64_t> step_edge_q16(const std::int32_t* profile_q8, int count, bool rising,
                                          const EdgeKernelSettings& settings = {});

// The step edge on the straight segment from `from` to `to` (pixels), sampled every
// `sample_step_px`: where along it the image steps up (rising) or down, as a pixel position. Empty
// when the segment leaves the image or shows no such step.
std::optional<geometry::Point2> step_edge_on_segment(const GrayView& image, geometry::Point2 from,
                                                     geometry::Point2 to, bool rising,
                                                     const EdgeKernelSettings& settings = {});

// Double-precision references of the same computations.
double sample_reference(const GrayView& image, double x, double y);
std::optional<double> step_edge_reference(const std::vector<double>& profile, bool rising,
                                          const EdgeKernelSettings& settings = {});

}  // namespace calbox::vision
