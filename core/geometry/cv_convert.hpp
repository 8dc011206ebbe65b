#pragma once
// Conversions between core's plain types and OpenCV's; include only from .cpp files.
#include <opencv2/core.hpp>
#include <vector>

#include "core/geometry/camera_model.hpp"
#include "core/geometry/types.hpp"
#include "core/image_view.hpp"

namespace calbox::geometry {

inline std::vector<cv::Point2d> to_cv(const std::vector<Point2>& points) {
    std::vector<cv::Point2d> out;
    out.reserve(points.size());
    for (const auto& p : points) out.emplace_back(p.x, p.y);
    return out;
}

template <class P>
std::vector<Point2> from_cv(const std::vector<P>& points) {
    std::vector<Point2> out;
    out.reserve(points.size());
    for (const auto& p : points) out.push_back({p.x, p.y});
    return out;
}

inline cv::Mat camera_matrix_of(const CameraModel& c) {
    return cv::Mat(3, 3, CV_64F, const_cast<double*>(c.camera_matrix.data())).clone();
}

// Wraps the view's pixels without copying; the view must outlive the Mat.
inline cv::Mat to_cv(const vision::GrayView& view) {
    view.check();
    return cv::Mat(view.height_px, view.width_px, CV_8UC1, const_cast<std::uint8_t*>(view.pixels),
                   static_cast<std::size_t>(view.stride_bytes));
}

}  // namespace calbox::geometry
