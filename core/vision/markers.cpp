#include "core/vision/markers.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/core/version.hpp>
#include <optional>

#include "core/geometry/cv_convert.hpp"
#include "core/geometry/line_fit.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "core/number_text.hpp"
#include "core/vision/edge_kernel.hpp"

#if CV_VERSION_MAJOR > 4 || (CV_VERSION_MAJOR == 4 && CV_VERSION_MINOR >= 7)
#include <opencv2/objdetect/aruco_detector.hpp>
#define CALBOX_ARUCO_DETECTOR_API 1
#else
#include <opencv2/aruco.hpp>
#define CALBOX_ARUCO_DETECTOR_API 0
#endif

namespace calbox::vision {
namespace {

using geometry::fit_line;
using geometry::intersect;
using geometry::Line;
using geometry::Point2;

struct RawMarkers {
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    int cells_per_side = 0;
};

// The adapter: OpenCV 4.7 moved ArUco into objdetect with a detector object.
RawMarkers opencv_detect(const cv::Mat& gray, int dictionary_id) {
    RawMarkers raw;
#if CALBOX_ARUCO_DETECTOR_API
    const cv::aruco::Dictionary dictionary = cv::aruco::getPredefinedDictionary(dictionary_id);
    cv::aruco::DetectorParameters parameters;
    parameters.cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    cv::aruco::ArucoDetector(dictionary, parameters).detectMarkers(gray, raw.corners, raw.ids);
    raw.cells_per_side = dictionary.markerSize + 2;
#else
    const auto dictionary = cv::aruco::getPredefinedDictionary(dictionary_id);
    const auto parameters = cv::aruco::DetectorParameters::create();
    parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    cv::aruco::detectMarkers(gray, dictionary, raw.corners, raw.ids, parameters);
    raw.cells_per_side = dictionary->markerSize + 2;
#endif
    return raw;
}

// Edge points along the side from p to q (clockwise order: the marker lies to the right).
std::vector<Point2> edge_points(const GrayView& image, Point2 p, Point2 q, int cells_per_side) {
    const double length = std::hypot(q.x - p.x, q.y - p.y);
    std::vector<Point2> out;
    if (length < 8) return out;
    const Point2 d{(q.x - p.x) / length, (q.y - p.y) / length};
    const Point2 outward{d.y, -d.x};
    // The profile spans the black border cell and the white quiet zone, no further.
    const double half = std::clamp(0.45 * length / cells_per_side, 1.5, 4.0);
    const double margin = std::max(0.1 * length, half + 1.0);
    // Profiles every half pixel along the edge, clear of its corners.
    const int profiles = static_cast<int>((length - 2 * margin) / 0.5) + 1;
    for (int i = 0; i < profiles; ++i) {
        const double t = margin + 0.5 * i;
        const Point2 on{p.x + d.x * t, p.y + d.y * t};
        const auto edge =
            step_edge_on_segment(image, {on.x - outward.x * half, on.y - outward.y * half},
                                 {on.x + outward.x * half, on.y + outward.y * half}, true);
        if (edge) out.push_back(*edge);
    }
    return out;
}

}  // namespace

RefinedCorners refine_marker_corners(const GrayView& image, const std::array<Point2, 4>& rough,
                                     int cells_per_side, const geometry::CameraModel* camera,
                                     const MarkerRefineLimits& limits) {
    static constexpr std::array<const char*, 4> kEdgeNames = {"top", "right", "bottom", "left"};
    const auto kept = [&](std::string why) {
        const double s = limits.unrefined_corner_sigma_px;
        return RefinedCorners{rough, false, std::move(why), {s, s, s, s}};
    };
    // Edge profiles are taken every half pixel and each reads a 2x2 neighbourhood: only every
    // second one carries noise of its own.
    constexpr double kIndependentProfileShare = 0.5;
    std::array<std::vector<Point2>, 4> edges;
    std::array<Line, 4> lines;
    std::vector<Point2> fitted_corners;  // in the edges' coordinates (normalised with a camera)
    std::array<Point2, 4> corners = rough;
    for (int pass = 0; pass < 2; ++pass) {
        for (std::size_t k = 0; k < 4; ++k) {
            auto& points = edges[k];
            points = edge_points(image, corners[k], corners[(k + 1) % 4], cells_per_side);
            if (points.size() < limits.min_edge_points) {
                return kept(std::string("the ") + kEdgeNames[k] + " edge gave " +
                            std::to_string(points.size()) + " points (at least " +
                            std::to_string(limits.min_edge_points) + " needed)");
            }
            if (camera != nullptr) points = geometry::undistort_to_normalized(*camera, points);
            lines[k] = fit_line(points);
        }
        fitted_corners.clear();
        for (std::size_t k = 0; k < 4; ++k) {
            const auto c = intersect(lines[(k + 3) % 4], lines[k]);
            if (!c) return kept("two edges fitted parallel");
            fitted_corners.push_back(*c);
        }
        auto refined = camera != nullptr
                           ? geometry::distort_from_normalized(*camera, fitted_corners)
                           : fitted_corners;
        for (std::size_t k = 0; k < 4; ++k) {
            const double moved = std::hypot(refined[k].x - rough[k].x, refined[k].y - rough[k].y);
            if (moved > limits.max_corner_move_px) {
                return kept("corner " + std::to_string(k) + " moved " + number_text("%.1f", moved) +
                            " px from OpenCV's (at most " +
                            number_text("%.1f", limits.max_corner_move_px) + ")");
            }
            corners[k] = refined[k];
        }
    }
    // A corner moves with either edge's offset across it: per coordinate, the two offsets'
    // RMS over the sine of the angle between the edges.
    const double pixels_per_unit = camera != nullptr ? camera->fx() : 1.0;
    std::array<double, 4> sigma_px{};
    for (std::size_t k = 0; k < 4; ++k) {
        const auto& a = lines[(k + 3) % 4];
        const auto& b = lines[k];
        const double sa = geometry::line_sigma_at(a, edges[(k + 3) % 4], fitted_corners[k],
                                                  kIndependentProfileShare);
        const double sb =
            geometry::line_sigma_at(b, edges[k], fitted_corners[k], kIndependentProfileShare);
        const double sine = std::abs(a.direction.x * b.direction.y - a.direction.y * b.direction.x);
        sigma_px[k] = pixels_per_unit * std::sqrt((sa * sa + sb * sb) / 2) / sine;
    }
    return {corners, true, {}, sigma_px};
}

std::vector<DetectedMarker> detect_markers(const GrayView& image, const MarkerOptions& options) {
    const int dictionary_id = geometry::aruco_dictionary_id(options.dictionary);
    const RawMarkers raw = opencv_detect(geometry::to_cv(image), dictionary_id);
    std::vector<DetectedMarker> out;
    for (std::size_t m = 0; m < raw.ids.size(); ++m) {
        DetectedMarker marker;
        marker.id = raw.ids[m];
        for (int k = 0; k < 4; ++k) {
            marker.corners[static_cast<std::size_t>(k)] = {
                raw.corners[m][static_cast<std::size_t>(k)].x,
                raw.corners[m][static_cast<std::size_t>(k)].y};
        }
        if (options.refine_edges) {
            auto r = refine_marker_corners(image, marker.corners, raw.cells_per_side,
                                           options.camera, options.refine_limits);
            marker.corners = r.corners;
            marker.refined = r.refined;
            marker.unrefined_because = std::move(r.unrefined_because);
            marker.corner_sigma_px = r.sigma_px;
        } else {
            marker.unrefined_because = "refinement off";
            marker.corner_sigma_px.fill(options.refine_limits.unrefined_corner_sigma_px);
        }
        out.push_back(marker);
    }
    std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
    return out;
}

}  // namespace calbox::vision
