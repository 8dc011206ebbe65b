#include "tests/bench/seed_pipelines.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace calbox::bench {

SeedUndistort seed_undistort_maps(const geometry::CameraModel& camera) {
    SeedUndistort out;
    const auto& k = camera.camera_matrix;
    out.camera_matrix = cv::Matx33d(k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7], k[8]);
    const cv::Size size(camera.image_width, camera.image_height);
    const cv::Mat distortion(camera.distortion, true);
    if (camera.model == geometry::LensModel::fisheye)
        cv::fisheye::initUndistortRectifyMap(out.camera_matrix, distortion, cv::Matx33d::eye(),
                                             out.camera_matrix, size, CV_16SC2, out.map1, out.map2);
    else
        cv::initUndistortRectifyMap(out.camera_matrix, distortion, cv::Matx33d::eye(),
                                    out.camera_matrix, size, CV_16SC2, out.map1, out.map2);
    return out;
}

int seed_delta_frame(const cv::Mat& gray, const SeedUndistort& undistort, double marker_mm) {
    cv::Mat flat, binary, small;
    cv::remap(gray, flat, undistort.map1, undistort.map2, cv::INTER_LINEAR);
    cv::adaptiveThreshold(flat, binary, 255, cv::ADAPTIVE_THRESH_GAUSSIAN_C, cv::THRESH_BINARY, 51,
                          2);
    const double scale = 1280.0 / flat.cols;
    cv::resize(flat, small, {}, scale, scale, cv::INTER_AREA);
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    const auto dictionary = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
    cv::aruco::detectMarkers(small, dictionary, corners, ids);
    int ends = 0;
    const float half = static_cast<float>(marker_mm / 2);
    const std::vector<cv::Point3f> square{
        {-half, half, 0}, {half, half, 0}, {half, -half, 0}, {-half, -half, 0}};
    for (auto& c : corners) {
        for (auto& p : c) p *= static_cast<float>(1 / scale);
        cv::Vec3d rvec, tvec;
        cv::solvePnP(square, c, undistort.camera_matrix, cv::noArray(), rvec, tvec, false,
                     cv::SOLVEPNP_IPPE_SQUARE);
        // The marker's y axis in the image, sampled over six of its sides along the bar.
        std::vector<cv::Point3f> axis{{0, 0, 0}, {0, 6 * 2 * half, 0}};
        std::vector<cv::Point2f> ends_px;
        cv::projectPoints(axis, rvec, tvec, undistort.camera_matrix, cv::noArray(), ends_px);
        cv::LineIterator it(binary, ends_px[0], ends_px[1], 8);
        std::vector<double> profile(static_cast<std::size_t>(it.count));
        for (int i = 0; i < it.count; ++i, ++it) profile[static_cast<std::size_t>(i)] = **it;
        double largest = 0;
        for (std::size_t i = 1; i < profile.size(); ++i)
            largest = std::max(largest, std::abs(profile[i] - profile[i - 1]));
        ends += largest > 0;
    }
    return ends;
}

int seed_planar_frame(const cv::Mat& gray, const SeedUndistort& undistort) {
    cv::Mat flat, binary;
    cv::remap(gray, flat, undistort.map1, undistort.map2, cv::INTER_LINEAR);
    cv::threshold(flat, binary, 0, 255, cv::THRESH_BINARY_INV | cv::THRESH_OTSU);
    cv::morphologyEx(binary, binary, cv::MORPH_OPEN,
                     cv::getStructuringElement(cv::MORPH_ELLIPSE, {5, 5}));
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(binary, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
    int holes = 0;
    for (const auto& c : contours) {
        if (c.size() < 6) continue;
        const cv::RotatedRect e = cv::fitEllipse(c);
        holes += e.size.width > 0 && e.center.x >= 0;
    }
    return holes;
}

int seed_galvo_frame(const cv::Mat& gray, cv::Size grid, int pitch_px) {
    cv::Mat clean;
    cv::medianBlur(gray, clean, 5);
    std::vector<cv::Point2f> centres;
    cv::SimpleBlobDetector::Params params;
    params.maxArea = 1e6f;
    params.filterByConvexity = false;
    params.filterByInertia = false;
    const bool found = cv::findCirclesGrid(clean, grid, centres, cv::CALIB_CB_SYMMETRIC_GRID,
                                           cv::SimpleBlobDetector::create(params));
    if (!found) return 0;
    std::vector<cv::Point2f> ideal;
    for (int r = 0; r < grid.height; ++r)
        for (int c = 0; c < grid.width; ++c)
            ideal.emplace_back(static_cast<float>((c + 1) * pitch_px),
                               static_cast<float>((r + 1) * pitch_px));
    const cv::Mat h = cv::findHomography(centres, ideal);
    cv::Mat warped;
    cv::warpPerspective(clean, warped, h,
                        {(grid.width + 1) * pitch_px, (grid.height + 1) * pitch_px});
    std::vector<cv::Vec3f> circles;
    cv::HoughCircles(warped, circles, cv::HOUGH_GRADIENT, 1, 0.8 * pitch_px, 100, 20,
                     static_cast<int>(0.3 * pitch_px), static_cast<int>(0.5 * pitch_px));
    return static_cast<int>(centres.size() + circles.size());
}

Timings interleaved_medians(const std::function<void()>& box, const std::function<void()>& seed,
                            int runs) {
    std::vector<double> b, s;
    const auto timed = [](const std::function<void()>& f) {
        const auto start = std::chrono::steady_clock::now();
        f();
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    for (int i = 0; i < runs; ++i) {
        b.push_back(timed(box));
        s.push_back(timed(seed));
    }
    std::sort(b.begin(), b.end());
    std::sort(s.begin(), s.end());
    return {b[b.size() / 2], s[s.size() / 2]};
}

}  // namespace calbox::bench
