#pragma once
// What the renderer's tests (test_renderer*.cpp) share: OpenCV's own projection and corner finder
// to judge the twin's camera by, and overhead cameras over the bed.
#include <CppUTest/TestHarness.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "board/sim/camera_reference.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/photo_cache.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/scenes.hpp"

using namespace calbox;
using namespace calbox::sim;

namespace renderer_checks {

inline CameraIntrinsics pinhole_1080p() {
    CameraIntrinsics c;
    c.model = LensModel::pinhole;
    c.width_px = 1920;
    c.height_px = 1080;
    c.fx = 1500;
    c.fy = 1502;
    c.cx = 962.3;
    c.cy = 537.8;
    c.distortion = {-0.12, 0.08, 0.0007, -0.0005, -0.01};
    return c;
}

inline CameraIntrinsics fisheye_1080p() {
    CameraIntrinsics c = pinhole_1080p();
    c.model = LensModel::fisheye;
    c.fx = c.fy = 1100;
    c.distortion = {-0.03, 0.01, -0.004, 0.0008};
    return c;
}

inline cv::Mat camera_matrix(const CameraIntrinsics& c) {
    return (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
}

// The board centred in front of the camera at 400 mm, tilted `tilt_deg` about its x axis.
inline Pose board_pose(double centre_x_mm, double centre_y_mm, double tilt_deg,
                       double distance_mm) {
    Pose p;
    p.rotation = rotation_from_vector({radians(tilt_deg), 0, 0});
    const Vec3 centre = p.rotation * Vec3{centre_x_mm, centre_y_mm, 0};
    p.translation_mm = Vec3{0, 0, distance_mm} - centre;
    return p;
}

inline std::vector<cv::Point2d> opencv_projection(const CameraIntrinsics& c, const Pose& pose,
                                                  const std::vector<cv::Point3d>& points) {
    const Vec3 r = vector_from_rotation(pose.rotation);
    const cv::Vec3d rvec(r.x, r.y, r.z);
    const cv::Vec3d tvec(pose.translation_mm.x, pose.translation_mm.y, pose.translation_mm.z);
    std::vector<cv::Point2d> out;
    if (c.model == LensModel::fisheye) {
        cv::fisheye::projectPoints(points, out, rvec, tvec, camera_matrix(c), c.distortion);
    } else {
        cv::projectPoints(points, rvec, tvec, camera_matrix(c), c.distortion, out);
    }
    return out;
}

inline cv::Mat as_mat(const GrayImage& image) {
    return cv::Mat(image.height_px, image.width_px, CV_8UC1,
                   const_cast<std::uint8_t*>(image.pixels.data()))
        .clone();
}

// RMS distance from each detected corner to the nearest OpenCV projection of a board corner.
inline double rms_to_nearest(const std::vector<cv::Point2f>& found,
                             const std::vector<cv::Point2d>& truth) {
    double sum = 0;
    for (const auto& f : found) {
        double best = 1e300;
        for (const auto& t : truth) best = std::min(best, std::hypot(f.x - t.x, f.y - t.y));
        sum += best * best;
    }
    return std::sqrt(sum / found.size());
}

inline double chessboard_corner_rms(const CameraIntrinsics& camera) {
    const auto spec = geometry::parse_pattern_spec("chessboard:9x6@20");
    const Pose pose = board_pose(80, 50, 10, 400);
    const BoardScene scene(spec, 4);
    // OpenCV's saddle refinement is biased by up to 0.07 px on perfectly sharp X-junctions
    // (the rendered edges themselves are exact to 0.002 px); a defocused lens, as on the box,
    // and a wide window take that away, so what is left measures the renderer.
    PhotoSettings photo;
    photo.blur_sigma_px = 2.0;
    const GrayImage image = render_photo(camera, pose, scene, photo);
    const cv::Mat gray = as_mat(image);
    std::vector<cv::Point2f> corners;
    CHECK_TRUE(cv::findChessboardCorners(gray, cv::Size(9, 6), corners));
    cv::cornerSubPix(gray, corners, cv::Size(15, 15), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
    std::vector<cv::Point3d> object;
    for (const auto& f : scene.features()) object.emplace_back(f.position_mm.x, f.position_mm.y, 0);
    CHECK_EQUAL(54u, corners.size());
    return rms_to_nearest(corners, opencv_projection(camera, pose, object));
}

}  // namespace renderer_checks

namespace renderer_checks {

// A photo's mean and standard deviation, in counts.
inline std::pair<double, double> mean_and_spread(const GrayImage& image) {
    double sum = 0, sum2 = 0;
    for (const auto p : image.pixels) {
        sum += p;
        sum2 += static_cast<double>(p) * p;
    }
    const double n = static_cast<double>(image.pixels.size());
    return {sum / n, std::sqrt(sum2 / n - (sum / n) * (sum / n))};
}

}  // namespace renderer_checks

namespace renderer_checks {

inline CameraIntrinsics overhead_camera() {
    CameraIntrinsics camera;
    camera.width_px = 400;
    camera.height_px = 300;
    camera.fx = camera.fy = 1000;  // 0.4 mm a pixel at 400 mm
    camera.cx = 199.5;
    camera.cy = 149.5;
    return camera;
}

// Where along a row the highlight's excess over the plain material is centred, in bed mm
// (0.4 mm a pixel, the camera over the origin), and how high it peaks.
inline std::pair<double, double> highlight_across_row(const std::vector<float>& albedo, int row,
                                                      double material) {
    double sum = 0, weighted = 0, peak = 0;
    for (int u = 0; u < 400; ++u) {
        const double excess = albedo[static_cast<std::size_t>(row) * 400 + u] - material;
        if (excess <= 0.01) continue;
        sum += excess;
        weighted += excess * u;
        peak = std::max(peak, excess);
    }
    if (sum == 0) return {0.0, 0.0};
    return {(weighted / sum - 199.5) * 0.4, peak};
}

}  // namespace renderer_checks

using namespace renderer_checks;
