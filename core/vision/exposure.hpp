#pragma once
// The box's own exposure: what the work area's light is in a frame, the exposure that puts its
// bright side below saturation and its dark side above the noise, and two exposures merged where
// one cannot hold both (the lamp's reflection on a glossy plate).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/image_view.hpp"

namespace calbox::vision {

// Every threshold the metering uses, with why.
struct MeteringLimits {
    // The work area is read in tiles (a grid this many across its bounding box), each tile's
    // light as its brightest (its 99.5th percentile: what is brightest there, the plate, the
    // sheet or a strand, less the odd speck). The bright side is the brightest tile's; the
    // dark side the dimmest tenth of the tiles' (where the light falls off: a tenth of the area
    // is more than a corner's few features, less than a black bed's bare stretches).
    int tiles_across = 12;
    double tile_brightest_percentile = 0.995;
    double dark_side_tile_share = 0.10;
    // A tile under this share of the work area's pixels in its box is left out (the area's
    // edge cuts it).
    double smallest_tile_share = 0.5;
    // A level at or above this is taken as clipped (JPEG and noise spread a clipped 255 down a
    // few counts).
    int clipped_from_dn = 250;
    // Where the bright side is put: headroom for the noise and a print's gloss under 255. A
    // frame whose bright side is already at this share of it or above, unclipped, with its dark
    // side high enough, is taken as it is (a capture saved).
    double bright_target_dn = 225;
    double bright_good_share = 0.85;
    // A bracket is taken only where its long exposure would give the dark side this many times
    // the light the single one gives (a black bed's bare stretches a little under the least are
    // not worth a second capture).
    double bracket_worth = 1.5;
    // A small hot spot (a glass plate's reflection) sets the bright side while most of the work
    // area lies far below it: when, after the exposure was cut for it, the middle tile would sit
    // under this share of the target, the long exposure puts it at the target instead, and the
    // hot spot comes from the short.
    double typical_least_share = 0.5;
    // The dark side must stand at least this far above black: four read-noise sigmas of a
    // worst-day sensor (6 counts), so that a dark mark there still differs from what is around it
    // by more than its noise. A black bed's bare stretches stand at 20-35.
    double dark_least_dn = 25;
    // The exposure never goes past this multiple of the frame metered, nor below this share:
    // a reading beyond is a wrong reading (a lens cap, the lamp off), not a scene.
    double largest_ratio = 8;
    double smallest_ratio = 1.0 / 16;
};

// Where the work is in the frame: inside the fixed reference marks (stuck outside the work area;
// their centres' hull, drawn a tenth of the way in towards its middle, clear of the marks
// themselves); with fewer than three marks, the frame less a border of `border_share` of each
// side.
std::vector<geometry::Point2> work_area_inside(const std::vector<geometry::Point2>& mark_centres_px,
                                               int width_px, int height_px,
                                               double border_share = 0.07);

// The light over the work area of one frame.
struct WorkAreaLight {
    double bright_dn = 0;      // the brightest tile's light
    double typical_dn = 0;     // the middle tile's light
    double dark_dn = 0;        // the dimmest tenth of the tiles' light
    double clipped_share = 0;  // of the work area's pixels, at or above clipped_from_dn
    std::size_t pixels = 0;    // in the work area
};

// Reads the work area: the polygon `area_px` (in order, at least three corners; clipped to the
// frame). Throws std::invalid_argument for fewer corners or an area outside the frame.
WorkAreaLight meter_work_area(const GrayView& frame, const std::vector<geometry::Point2>& area_px,
                              const MeteringLimits& limits = {});

// What to capture next, as multiples of the exposure the reading was taken at.
struct ExposurePlan {
    enum class Step {
        meter_again,  // the bright side was clipped: read again at `ratio` (a half) to see it
        single,       // one exposure at `ratio` holds both sides
        bracket,      // the long exposure at `ratio` lifts the dark side, the short one at
                      // `short_ratio` keeps the bright side below saturation; merged
    };
    Step step = Step::single;
    double ratio = 1;
    double short_ratio = 1;
    std::string why;  // one line: the figures that decided it
};
// `after_cuts`: the reading was taken after the exposure was cut for a clipped bright side (a
// hot spot): then, and only then, a dim middle of the work area is the cut's doing, not a dark
// surface (a black bed), and worth a long exposure.
ExposurePlan plan_exposure(const WorkAreaLight& light, const MeteringLimits& limits = {},
                           bool after_cuts = false);

// Two frames of the same scene merged: the long exposure where it is below clipping, scaled by
// `long_over_short` (the exposures' ratio) to the short one's levels; the short exposure where the
// long one clipped. The dark side keeps the long exposure's signal over its noise; the result is
// on the short exposure's scale. Throws std::invalid_argument for frames of different sizes or a
// ratio under 1.
struct MergedFrame {
    int width_px = 0;
    int height_px = 0;
    std::vector<std::uint8_t> pixels;  // row-major, no padding
    double from_short_share = 0;       // of the pixels, taken from the short exposure
};
MergedFrame merge_bracket(const GrayView& long_frame, const GrayView& short_frame,
                          double long_over_short, const MeteringLimits& limits = {});

// Otsu's level between a photo's dark and bright parts from its grey histogram: the level
// (counts at or below it dark) that leaves the two classes' means furthest apart, weighted by
// their shares, computed as OpenCV's THRESH_OTSU does on the same counts (a caller that has
// the histogram need not pass over the photo again).
int otsu_level(const std::array<double, 256>& histogram);

}  // namespace calbox::vision
