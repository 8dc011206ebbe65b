#pragma once
// The twin's own camera: OpenCV's pinhole (k1 k2 p1 p2 k3) and fisheye (k1..k4) models,
// written from OpenCV's documented equations and checked against cv::projectPoints in tests.
#include <string>
#include <vector>

#include "board/sim/vec.hpp"
#include "core/geometry/camera_model.hpp"

namespace calbox::sim {

struct Vec2 {
    double x = 0, y = 0;
};

enum class LensModel { pinhole, fisheye };

struct CameraIntrinsics {
    LensModel model = LensModel::pinhole;
    int width_px = 1920;
    int height_px = 1080;
    double fx = 1500, fy = 1500, cx = 959.5, cy = 539.5;
    std::vector<double> distortion;  // pinhole: k1 k2 p1 p2 k3; fisheye: k1 k2 k3 k4 (missing = 0)
};

// A rigid transform from a plane's frame (bed, board) to the camera frame, as OpenCV's rvec/tvec.
struct Pose {
    Mat3 rotation;
    Vec3 translation_mm;
    Vec3 apply(const Vec3& p) const { return rotation * p + translation_mm; }
    Vec3 camera_centre_in_plane() const { return rotation.transposed() * (translation_mm * -1.0); }
};

// Camera at `position_mm` looking at `look_at_mm` (both in the plane's frame, z up), image up
// along the plane's +y as far as the view allows, then rolled about the optical axis.
Pose look_at_pose(const Vec3& position_mm, const Vec3& look_at_mm, double roll_deg);

// outer after inner: points go through `inner` first.
Pose compose(const Pose& outer, const Pose& inner);

// A board (OpenCV's frame: y down the printed board, z into it) lying face up on the bed with its
// origin at `origin_mm` (z: the board's surface height), turned `angle_deg` about the bed's z.
Pose board_lying_on_bed(const Vec3& origin_mm, double angle_deg);

// The same camera as core's model (pinhole distortion padded to five coefficients).
geometry::CameraModel as_camera_model(const CameraIntrinsics& c);

Vec2 distort_normalized(const CameraIntrinsics& c, double x, double y);  // -> pixel
Vec2 undistort_pixel(const CameraIntrinsics& c, double u, double v);     // -> normalized x/z, y/z
// The same from a guess near the answer (a neighbouring pixel's): it converges to the same point
// in two or three steps instead of five.
Vec2 undistort_pixel_from(const CameraIntrinsics& c, double u, double v, Vec2 start);
Vec2 project_point(const CameraIntrinsics& c, const Pose& plane_to_camera, const Vec3& p);

}  // namespace calbox::sim
