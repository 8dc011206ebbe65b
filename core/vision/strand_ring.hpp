#pragma once
// A single strand laid as a square ring around a marker, measured on both its edges. A first
// layer's strand spreads where the nozzle pressed it and narrows where it did not, so its edges
// move with its width; its centreline stays where the nozzle went. The ring's corners are the
// intersections of its sides' centrelines, and its width says how high the strand stands.
#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/camera_model.hpp"
#include "core/vision/edge_kernel.hpp"
#include "core/image_view.hpp"

namespace calbox::vision {

// Where the ring lies around its marker, in the marker's own millimetres (its centre at the
// origin, +y towards its top edge as printed).
struct StrandRingLayout {
    double marker_half_mm = 6;      // the marker's black border, centre to edge
    double ring_half_mm = 9.725;    // centre to the ring's centreline
    double strand_width_mm = 0.45;  // as commanded
    double gap_mm = 1.5;            // bare bed inside the ring, as commanded
};

// Every threshold the ring measurement uses, with why.
struct StrandRingLimits {
    // Profiles stay this share of a side clear of its corners (the turning nozzle rounds them)
    // and of its middle (where a ring starts and stops, a blob or a seam).
    double corner_clearance_share = 0.15;
    double seam_clearance_share = 0.06;
    // One profile every this many millimetres along a side: a few pixels apart at 0.07 mm/px,
    // each reading its own noise.
    double profile_step_mm = 0.25;
    // Each edge is looked for this far past the strand's commanded edge on its side: a strand
    // pressed to a millimetre still ends inside it, the next row's ring (a millimetre and a
    // half away) and the quiet zone's fill (the gap inside) do not enter.
    double reach_outside_mm = 0.8;
    // How far the strand's centreline may lie from where it is expected: the marker's own
    // edges, which place the first pass, move with their strands' widths by up to a quarter
    // millimetre, scaled up from the marker to the ring.
    double centre_uncertainty_mm = 0.5;
    // A side whose profiles found both edges fewer times than this gives no centreline.
    std::size_t min_profiles_per_side = 8;
    // A strand narrower than this share of its commanded width, or wider than this multiple,
    // is not the strand (a speck, a neighbour's edge): a free bead is 0.59 of a 0.45 x 0.2 mm
    // line, and a nozzle's flat spreads it to about twice.
    double narrowest_share = 0.35;
    double widest_multiple = 3.0;
    // The strand's middle stands brighter than the bed just past it by at least this many grey
    // levels: filament on a sheet differs by tens (a grey strand on a black sheet, over forty),
    // while on bare bed the kernel still finds the sensor noise's steepest steps, a few levels.
    double min_contrast_dn = 8;
    // The blur is fitted over the strand and this much bare bed on either side of its edges:
    // three times a soft corner's blur at 7 px/mm, short of the gap's fill inside and the next
    // row's ring outside, however far a squashed strand spread; each fit starts from a blur of
    // a pixel.
    double bar_fit_margin_mm = 0.75;
    double bar_start_blur_px = 1.0;
    // The blur across a side's strand (strand_across_side) above this share of its width (the
    // edge centroids') leaves the width untold. On the twin's worst day (6 grey levels of noise,
    // JPEG at 68) a 12 MP camera's sides show 0.23-0.25 and a sharp 2 MP camera's up to 0.31,
    // their heights within 0.02 mm of the material's; a 2 MP camera's soft corners 0.33-0.42,
    // where the heights told with a share of 0.45 were up to 0.05 mm off.
    double widest_blur_share = 0.33;
    EdgeKernelSettings edges;
};

struct StrandRing {
    // The centrelines' intersections in raw pixels, in the marker's corner order (OpenCV's:
    // top-left, top-right, bottom-right, bottom-left as printed), each with its standard
    // uncertainty per coordinate from the centrelines' own scatter.
    std::array<geometry::Point2, 4> corners_px{};
    std::array<double, 4> sigma_px{};
    // The strand's width at each corner, in pixels: each side's widths fitted along it (a gap
    // that changes across the bed changes them steadily) and the two sides' values there
    // averaged, with the standard uncertainty of that figure.
    std::array<double, 4> width_px{};
    std::array<double, 4> width_sigma_px{};
    // Why a corner's width (and the height it says) was not measured: empty when it was. A
    // corner whose width is not measured is still placed where the centrelines meet.
    std::array<std::string, 4> width_unmeasured_because;
    std::string unmeasured_because;  // empty when measured
    bool measured() const { return unmeasured_because.empty(); }
};

// One profile across a single strand: its edge to bare bed looked for on the segment `from` ->
// `to` (pixels; material to bed going that way: the segment starts inside the strand, or on the
// bed before it, and ends on the bed past it), then its other edge back from there, within a
// widest strand's width and no nearer than a narrowest one's (the limits'). `px_per_mm` along
// the segment; `strand_width_mm` as commanded. Empty when either edge is missing, the width is
// not a strand's, or its middle is not brighter than the bed past it (no strand there).
struct StrandCrossing {
    geometry::Point2 centre_px;  // midway between its edges
    double width_px = 0;         // between the edge kernel's centroids
    // The profile across it for the blur's fit: the strand and bare bed on either side (the
    // limits' bar_fit_margin_mm), sampled every `profile_step_px`, the centroids' midpoint
    // `middle_px` from its start; the strand's middle above the bed past it.
    std::vector<double> profile;
    double profile_step_px = 0;
    double middle_px = 0;
    double contrast_dn = 0;
};
std::optional<StrandCrossing> strand_across(const GrayView& image, geometry::Point2 from,
                                            geometry::Point2 to, double px_per_mm,
                                            double strand_width_mm,
                                            const StrandRingLimits& limits = {});

// A strand's profile across it fitted as a bar seen through a Gaussian blur: the background on
// either side (a level and a slope), the bar's brightness above it, its centre, its width and the
// blur. `profile` is sampled every `step_px` from its start; positions are in pixels from there.
// Empty when the fit does not settle. Fitted free on one noisy profile, a blur of a third of the
// width lets the width, the brightness and the blur trade (their product is most of what it
// shows); a side's profiles share the brightness and the blur, so the ring fits them once on the
// side's profiles averaged (strand_across_side) and each profile's width with them held.
struct BlurredBar {
    double centre_px = 0;
    double width_px = 0;
    double blur_sigma_px = 0;
    double contrast_dn = 0;
};
enum class BarFit { free, contrast_and_blur_held };
std::optional<BlurredBar> fit_blurred_bar(const std::vector<double>& profile, double step_px,
                                          const BlurredBar& start, BarFit fit = BarFit::free);

// The blurred bar of a side's profiles averaged about their middles: the strand's brightness
// there and the lens's blur across it. The edge kernel's centroids place a strand's edges where
// the blur is small against its width; a wider blur pulls the two edges' lobes apart and widens
// the strand (at 7 px/mm, a 3 px strand under 1.2 px of blur, a lens's soft corners, by half a
// pixel: its height 0.06 mm low). The ring takes each profile's width from its own bar with
// these held, and tells no width where the blur is over the limits' share of it. Empty, with
// why, when the side has too few profiles or they do not fit.
std::optional<BlurredBar> strand_across_side(const std::vector<StrandCrossing>& crossings,
                                             const StrandRingLimits& limits, std::string& why_not);

// A first-layer strand's height from its width, the cross-section known from the job: pressed
// by the nozzle it is as high as the cross-section over its width; as narrow as a free bead
// (sqrt(pi A / 4), the section over its own diameter) or narrower it is one, its top at that
// diameter sqrt(4 A / pi) whatever the gap under it (which the width then cannot tell).
struct StrandHeight {
    double height_mm = 0;
    double sigma_mm = 0;
    bool free_bead = false;
    // Spread as wide as a nozzle's flat lets it: the nozzle scraped the bed, and the strand is
    // no higher than its cross-section over that width: the height given is half that bound,
    // its uncertainty the same.
    bool scraped = false;
};
// A 0.4 mm nozzle's flat tip is about a millimetre across: a strand pressed wider than 95 % of
// it is taken as scraped (the twin's own nozzle has the same flat).
constexpr double kNozzleFlatMm = 1.0;
constexpr double kScrapedFromShare = 0.95;
// A free bead's top, per coordinate of what stands in its way: a real bead sags and flattens
// on the bed by a few hundredths.
constexpr double kFreeBeadHeightSigmaMm = 0.02;
StrandHeight strand_height_from_width(double section_mm2, double width_mm, double width_sigma_mm);

// Measures the ring around a marker whose four corners (raw pixels, OpenCV's order) were found.
// With a camera the centrelines are fitted as straight lines after undistortion.
StrandRing measure_strand_ring(const GrayView& image,
                               const std::array<geometry::Point2, 4>& marker_corners_px,
                               const StrandRingLayout& layout, const geometry::CameraModel* camera,
                               const StrandRingLimits& limits = {});

}  // namespace calbox::vision
