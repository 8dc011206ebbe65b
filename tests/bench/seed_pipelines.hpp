#pragma once
// The seed papers' pipelines (../shared/REFERENCE.md), done again with OpenCV on the frame the box
// measures: the speed baseline each benchmark reports its ratio against. Not the box's code; the
// answers are only counted, so that the work is done and not optimised away.
#include <functional>
#include <opencv2/core.hpp>

#include "core/geometry/camera_model.hpp"

namespace calbox::bench {

// The undistortion maps, made once as the seed's calibration makes them (not timed).
struct SeedUndistort {
    cv::Mat map1, map2;
    cv::Matx33d camera_matrix;
};
SeedUndistort seed_undistort_maps(const geometry::CameraModel& camera);

// Section 1 (delta): undistort; adaptive threshold (Gaussian, 51 x 51); ArUco DICT_4X4_50 on a
// 1280-wide copy, corners scaled back; a pose per marker (solvePnP, as
// estimatePoseSingleMarkers); along each marker's y axis the intensity profile and its largest
// gradient. Returns the bar ends found.
int seed_delta_frame(const cv::Mat& gray, const SeedUndistort& undistort, double marker_mm);
// Section 2 (router): undistort; grey threshold (Otsu); noise removed (an opening); contours;
// ellipses fitted; centroids. Returns the holes found.
int seed_planar_frame(const cv::Mat& gray, const SeedUndistort& undistort);
// Section 4 (galvo): median filter (soot); findCirclesGrid, row by row; a homography to an ideal
// grid of `pitch_px` and the warp; HoughCircles for the large circles (radii 0.3 to 0.5 pitch).
// Returns the circles found (grid and large).
int seed_galvo_frame(const cv::Mat& gray, cv::Size grid, int pitch_px);

// The medians of `runs` interleaved timings of the box's work and the seed's, in seconds.
struct Timings {
    double box_s = 0, seed_s = 0;
    double ratio() const { return box_s / seed_s; }
};
Timings interleaved_medians(const std::function<void()>& box, const std::function<void()>& seed,
                            int runs);

}  // namespace calbox::bench
