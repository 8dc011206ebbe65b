#pragma once
// Round marks (burned spots, drilled holes, printed dots) found in a photo and their centres to
// a small fraction of a pixel: OpenCV finds the blobs, a fixed-point moment kernel measures each
// one on the image itself.
#include <cstdint>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/image_view.hpp"

namespace calbox::vision {

// Which side of its surroundings a mark is: what the mode knows (a drilled hole shows the dark
// backing, a burn is dark on a light substrate) or the machine file says where a machine differs.
enum class MarkPolarity { dark, light };

// Every threshold the spot finder uses, with why it is what it is.
struct SpotSettings {
    MarkPolarity polarity = MarkPolarity::dark;
    // The largest mark's diameter in the photo, roughly. Given, each pixel is compared with the
    // mean of a box three diameters across around it: what surrounds the work (a dark bed, a
    // grey floor, a white table) then moves no mark's level, where one Otsu level over the frame
    // splits the work from its surroundings and finds no mark. 0: one Otsu level.
    double mark_diameter_px = 0;
    // With the local level, a mark pixel lies this far past its box's mean: five times the
    // grey-level noise left after the median filter, well under any real mark's contrast.
    double local_contrast_dn = 8;
    // Where the work can be in the photo (a polygon in pixels; empty: anywhere): a blob whose
    // centre lies outside is not looked at, whatever it is (a wall, a lamp, the floor).
    std::vector<geometry::Point2> search_outline_px;
    // Soot specks and dust a few pixels across vanish under a median filter of this size; a mark
    // tens of pixels across keeps its edge where it was (the median of a straight edge is the
    // edge, and a circle's curvature shifts every side alike).
    int median_kernel_px = 5;
    // Below this many pixels a blob is noise or a speck the median missed, not a mark.
    int min_area_px = 20;
    // The moment window reaches this far beyond the blob's equivalent radius, so that the
    // blurred edge's partly covered pixels (a defocus of a pixel or two) are all inside it.
    double window_margin_px = 3.5;
};

struct Spot {
    geometry::Point2 centre_px;   // intensity-weighted centroid, OpenCV's pixel convention
    double sigma_px = 0;          // standard uncertainty of each coordinate, from the image noise
    double area_px = 0;           // the mark's area (sum of its weights), pixels
    double elongation = 1;        // major / minor axis of its second moments: 1 for a disc
    double contrast_dn = 0;       // substrate minus mark (dark marks) or the reverse
    bool touches_border = false;  // cut by the image's edge: its centre is not measurable
};

struct SpotImage {
    std::vector<Spot> spots;
    bool dark_marks = true;   // dark marks on a light substrate, or light on dark
    double threshold_dn = 0;  // Otsu's level between marks and substrate; 0 with a local level
};

// The marks of `settings.polarity`, against a local level or one Otsu level (SpotSettings).
// Throws std::invalid_argument for an empty image.
SpotImage find_spots(const GrayView& image, const SpotSettings& settings = {});

// The fixed-point moment kernel on its own: the centroid of a mark within a circular window,
// each pixel weighted by how far its grey level lies from the substrate's level towards the
// mark's, clamped to [0, 1] in Q16. The result's sigma comes from `noise_dn`, the grey-level
// noise of a substrate pixel.
struct MomentWindow {
    geometry::Point2 centre_px;
    double radius_px = 0;
    // The substrate's level at the window's centre and how it changes across the window: the
    // lamp mirrored by a glass or metal plate adds light that climbs tens of counts across one
    // mark, and a level held flat weighs the substrate on its dim side as mark, pulling the
    // centroid there by a tenth of a pixel and more. Glare adds to the mark and the substrate
    // alike, so the span between them (substrate_dn - mark_dn) stays the same across the window.
    double substrate_dn = 0, mark_dn = 0, noise_dn = 0;
    double substrate_slope_x_dn_per_px = 0, substrate_slope_y_dn_per_px = 0;
};
Spot measure_spot_q16(const GrayView& image, const MomentWindow& window);
// The same computation in double precision, the reference the kernel is tested against.
Spot measure_spot_reference(const GrayView& image, const MomentWindow& window);

}  // namespace calbox::vision
