#pragma once
// Round marks (burned spots, drilled holes, printed dots) found in a photo and their centres to
// a small fraction of a pixel: OpenCV finds the blobs, a fixed-point moment kernel measures each
// one on the image itself.
#include <cstdint>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/vision/image_view.hpp"

namespace calbox::vision {

// Every threshold the spot finder uses, with why it is what it is.
struct SpotSettings {
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
    double threshold_dn = 0;  // Otsu's level between marks and substrate
};

// The marks are whichever side of Otsu's threshold covers less of the image. Throws
// std::invalid_argument for an empty image.
SpotImage find_spots(const GrayView& image, const SpotSettings& settings = {});

// The fixed-point moment kernel on its own: the centroid of a mark within a circular window,
// each pixel weighted by how far its grey level lies from the substrate's level towards the
// mark's, clamped to [0, 1] in Q16. The result's sigma comes from `noise_dn`, the grey-level
// noise of a substrate pixel.
struct MomentWindow {
    geometry::Point2 centre_px;
    double radius_px = 0;
    double substrate_dn = 0, mark_dn = 0, noise_dn = 0;
};
Spot measure_spot_q16(const GrayView& image, const MomentWindow& window);
// The same computation in double precision, the reference the kernel is tested against.
Spot measure_spot_reference(const GrayView& image, const MomentWindow& window);

}  // namespace calbox::vision
