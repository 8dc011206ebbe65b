#pragma once
// ArUco markers: OpenCV finds and decodes them (behind one small adapter for the 4.6 and 4.7+
// APIs), AprilTag families libapriltag; the corners are then refined by fitting each outer edge
// over its length and intersecting neighbouring edges, which removes the bias of OpenCV's corner
// refinement on blurred corners.
#include <array>
#include <string>
#include <vector>

#include "core/geometry/camera_model.hpp"
#include "core/image_view.hpp"

namespace calbox::vision {

// A marker's corners as refined, or kept as the detector found them with the reason.
struct RefinedCorners {
    std::array<geometry::Point2, 4> corners;  // OpenCV's order: clockwise from the top-left
    // False when the edge refinement was off or failed: the corners are the detector's own
    // (about 0.2 px off on a blurred photo), and `unrefined_because` says why.
    bool refined = false;
    std::string unrefined_because;
    // Each corner's standard uncertainty per coordinate, in pixels: from the edge fits' own
    // scatter when refined, else what the detector's corners are worth.
    std::array<double, 4> sigma_px{};
};

struct DetectedMarker : RefinedCorners {
    int id = 0;
};

// Where each edge is looked for and how far a refined corner may move, with their reasons.
struct MarkerRefineLimits {
    // An edge fitted from fewer points than this is not a line: a side is profiled every half
    // pixel clear of its corners, so a side of 8 px (the shortest measured) gives 6 or more
    // when its edge is there.
    std::size_t min_edge_points = 6;
    // A refined corner further than this from OpenCV's has measured something else (a
    // neighbouring edge, a smudge): OpenCV's corners are within half a pixel on any photo
    // the detector decodes.
    double max_corner_move_px = 2.0;
    // What a corner kept as OpenCV found it is worth, per coordinate: its sub-pixel corners are
    // 0.2 px RMS from the truth on the twin's blurred photos (test_vision, Markers).
    double unrefined_corner_sigma_px = 0.2;
    // How far each profile reaches either side of the edge: this share of a cell, so that it
    // spans the black border cell and the white quiet zone and no further (the marker's bits lie
    // beyond), but at least enough pixels for a blurred step and at most what a cell of a large
    // marker needs.
    double profile_reach_cells = 0.45;
    double profile_reach_min_px = 1.5;
    double profile_reach_max_px = 4.0;
    // Profiles stay this share of the side (and a reach plus a pixel) clear of the corners, where
    // the neighbouring edge's step would enter them.
    double corner_clearance_share = 0.1;
};

// libapriltag's detector settings, with their reasons.
struct AprilTagLimits {
    // Bits of a code the decoder may correct: two, as AprilTag's authors advise (more costs
    // memory and false detections, fewer loses worn marks).
    int bits_corrected = 2;
    // Quads are looked for at full resolution: set-up and target photos are few, and on
    // AprilTag's own photos libapriltag's default decimation of 2 finds 34 of 47 tags where full
    // resolution finds 46 (small and far tags lose their quads when halved).
    float quad_decimate = 1.0F;
    // A second pass at this decimation (0: none) adds the tags the first missed: under motion
    // blur halving the image finds tags full resolution does not (the twin's 2 mm tags: 4 of
    // 48 against 1), and the photos are few.
    float second_pass_decimate = 2.0F;
    // A decode whose bits stand less than this far (grey levels) from their threshold is noise
    // read as a code: real marks on the twin's photos decode at 170-210, the false ones found
    // in a background at 2.
    float min_decision_margin = 30.0F;
};

// A rectangle of an image's pixels: columns x_px .. x_px + width_px - 1, likewise rows.
struct PixelWindow {
    int x_px = 0, y_px = 0, width_px = 0, height_px = 0;
    // The marks this window is for (empty: whatever it shows). Once the window's first look has
    // them all, its later looks (a second AprilTag decimation, the equalised photo) are skipped;
    // one missed by every look sends the search to the whole image (MarkerOptions::windows).
    std::vector<int> wanted_ids;
};

struct MarkerOptions {
    // OpenCV's ArUco dictionaries by OpenCV's names (DICT_4X4_50 ... DICT_APRILTAG_36h11), or
    // AprilTag families by libapriltag's (tag36h11, tag25h9, tagStandard41h12), which its own
    // detector then finds.
    std::string dictionary = "DICT_4X4_50";
    bool refine_edges = true;
    // With a camera, edges are fitted as straight lines after undistortion (they are straight on
    // the marker, not in the raw image); without one, in raw pixels.
    const geometry::CameraModel* camera = nullptr;
    MarkerRefineLimits refine_limits;
    AprilTagLimits apriltag_limits;
    // A second look on the image equalised tile by tile (CLAHE: tiles of the image's side over
    // `equalize_tiles`, each tile's histogram clipped at `equalize_clip_limit` times its mean),
    // adding the marks the photo itself did not give: marks in a dim, soft corner (the fixed
    // reference marks). It costs a second detection.
    bool equalized_pass = false;
    int equalize_tiles = 8;
    double equalize_clip_limit = 4.0;
    // Where to look, in pixels: empty for the whole image; else only inside these windows
    // (clipped to the image), each searched on its own (a few marks whose places are known cost
    // a few small detections, not the frame's). Corners are refined on the whole image. When a
    // window's wanted mark is not found in it (the camera or the bed moved, a mark covered), the
    // whole image is searched as if no window had been given (and with no smallest side), so that
    // what is then said of the photo is what the whole photo shows.
    std::vector<PixelWindow> windows;
    // The smallest marker side the search must find, in pixels (0: any size). Known, OpenCV's
    // ArUco looks on a copy scaled so that such a marker spans its decoding's 32 pixels (ArUco3,
    // Romero-Ramirez et al. 2018) and refines its corners back up to the photo itself.
    double smallest_side_px = 0;
};

// Markers sorted by id. Throws geometry::PatternError for an unknown dictionary name.
std::vector<DetectedMarker> detect_markers(const GrayView& image, const MarkerOptions& options);

// Refines a detector's corners of one marker whose found outline holds `cells_per_side` cells
// (its bits plus the black border), black inside a white zone or (`dark_inside` false, as
// AprilTag's standard families have it) white inside a black ring.
RefinedCorners refine_marker_corners(const GrayView& image,
                                     const std::array<geometry::Point2, 4>& rough,
                                     int cells_per_side, const geometry::CameraModel* camera,
                                     const MarkerRefineLimits& limits = {},
                                     bool dark_inside = true);

}  // namespace calbox::vision
