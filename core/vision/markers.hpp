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
};

struct MarkerOptions {
    std::string dictionary = "DICT_4X4_50";
    bool refine_edges = true;
    // With a camera, edges are fitted as straight lines after undistortion (they are straight on
    // the marker, not in the raw image); without one, in raw pixels.
    const geometry::CameraModel* camera = nullptr;
};

// Markers sorted by id. Throws geometry::PatternError for an unknown dictionary name.
std::vector<DetectedMarker> detect_markers(const GrayView& image, const MarkerOptions& options);

// Refines OpenCV's corners of one marker whose side holds `cells_per_side` cells (its bits plus
// the black border). Returns the rough corners unchanged when an edge cannot be measured.
std::array<geometry::Point2, 4> refine_marker_corners(const GrayView& image,
                                                      const std::array<geometry::Point2, 4>& rough,
                                                      int cells_per_side,
                                                      const geometry::CameraModel* camera);

}  // namespace calbox::vision
