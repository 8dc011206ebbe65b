#pragma once
// ArUco markers: OpenCV finds and decodes them (behind one small adapter for the 4.6 and 4.7+
// APIs); the corners are then refined by fitting each outer edge over its length and
// intersecting neighbouring edges, which removes the bias of OpenCV's corner refinement on
// blurred corners.
#include <array>
#include <string>
#include <vector>

#include "core/geometry/camera_model.hpp"
#include "core/vision/image_view.hpp"

namespace calbox::vision {

struct DetectedMarker {
    int id = 0;
    std::array<geometry::Point2, 4> corners;  // OpenCV's order: clockwise from the top-left
    // False when the edge refinement was off or failed: the corners are OpenCV's own (about
    // 0.2 px off on a blurred photo), and `unrefined_because` says why.
    bool refined = false;
    std::string unrefined_because;
    // Each corner's standard uncertainty per coordinate, in pixels: from the edge fits' own
    // scatter when refined, else what OpenCV's corners are worth.
    std::array<double, 4> corner_sigma_px{};
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
};

struct MarkerOptions {
    std::string dictionary = "DICT_4X4_50";
    bool refine_edges = true;
    // With a camera, edges are fitted as straight lines after undistortion (they are straight on
    // the marker, not in the raw image); without one, in raw pixels.
    const geometry::CameraModel* camera = nullptr;
    MarkerRefineLimits refine_limits;
};

// Markers sorted by id. Throws geometry::PatternError for an unknown dictionary name.
std::vector<DetectedMarker> detect_markers(const GrayView& image, const MarkerOptions& options);

// OpenCV's corners of one marker refined, or kept with the reason they could not be.
struct RefinedCorners {
    std::array<geometry::Point2, 4> corners;
    bool refined = false;
    std::string unrefined_because;
    std::array<double, 4> sigma_px{};  // as DetectedMarker::corner_sigma_px
};

// Refines OpenCV's corners of one marker whose side holds `cells_per_side` cells (its bits plus
// the black border).
RefinedCorners refine_marker_corners(const GrayView& image,
                                     const std::array<geometry::Point2, 4>& rough,
                                     int cells_per_side, const geometry::CameraModel* camera,
                                     const MarkerRefineLimits& limits = {});

}  // namespace calbox::vision
