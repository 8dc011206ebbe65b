#include "firmware/cycle/overlays.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/geometry/camera_model.hpp"
#include "firmware/cycle/png_picture.hpp"

namespace calbox::firmware {

std::string grid_overlay_png(const vision::GrayView& photo, const std::vector<GridMark>& marks,
                             const std::vector<geometry::Point2>& extra_mm, double z_mm,
                             const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                             const GridMarkStyle& style) {
    OverlayCanvas canvas = overlay_canvas_of(photo);
    const int thickness = canvas.size(std::max(1, photo.width_px / 1500));
    std::vector<geometry::Point3> points;
    points.reserve(marks.size() + extra_mm.size());
    for (const auto& m : marks) points.push_back({m.measured_mm.x, m.measured_mm.y, z_mm});
    for (const auto& e : extra_mm) points.push_back({e.x, e.y, z_mm});
    const auto px = geometry::project_points(camera, plane.bed_to_camera, points);
    const int photo_radius = std::max(4, photo.width_px / style.radius_divisor);
    const int radius = canvas.size(photo_radius);
    for (std::size_t i = 0; i < px.size(); ++i) {
        const cv::Point at = canvas.at(px[i].x, px[i].y);
        const bool mark = i < marks.size();
        cv::circle(canvas.picture, at, mark ? radius : 2 * radius,
                   mark ? cv::Scalar(0, 200, 0) : cv::Scalar(0, 140, 255), thickness);
        if (mark && marks[i].labelled) {
            const std::string label =
                std::to_string(marks[i].column) + "," + std::to_string(marks[i].row);
            cv::putText(canvas.picture, label,
                        at + cv::Point(style.label_offset_radii * radius, -radius),
                        cv::FONT_HERSHEY_SIMPLEX,
                        canvas.font_scale(photo.width_px / style.font_scale_divisor),
                        cv::Scalar(255, 0, 0), thickness);
        }
    }
    return png_of(canvas);
}

std::string error_field_png(const std::vector<FieldArrow>& arrows, const std::string& title) {
    if (arrows.empty()) throw std::invalid_argument("error field: no point");
    constexpr int kSize = 800, kMargin = 70;
    double x0 = arrows.front().at_mm.x, x1 = x0, y0 = arrows.front().at_mm.y, y1 = y0;
    double largest = 0;
    for (const auto& a : arrows) {
        x0 = std::min(x0, a.at_mm.x);
        x1 = std::max(x1, a.at_mm.x);
        y0 = std::min(y0, a.at_mm.y);
        y1 = std::max(y1, a.at_mm.y);
        largest = std::max(largest, std::hypot(a.error_mm.x, a.error_mm.y));
    }
    const double span_mm = std::max({x1 - x0, y1 - y0, 1.0});
    const double px_per_mm = (kSize - 2 * kMargin) / span_mm;
    // 1, 2 or 5 times a power of ten: the largest arrow near a twelfth of the span.
    double magnify = 1;
    if (largest > 0) {
        const double wanted = span_mm / 12 / largest;
        const double decade = std::pow(10.0, std::floor(std::log10(wanted)));
        magnify = wanted / decade >= 5 ? 5 * decade : wanted / decade >= 2 ? 2 * decade : decade;
    }
    cv::Mat picture(kSize, kSize, CV_8UC3, cv::Scalar(255, 255, 255));
    const auto at = [&](double x_mm, double y_mm) {
        return cv::Point2d(
            kMargin + (x_mm - x0) * px_per_mm + (span_mm - (x1 - x0)) * px_per_mm / 2,
            kSize - kMargin - (y_mm - y0) * px_per_mm - (span_mm - (y1 - y0)) * px_per_mm / 2);
    };
    for (const auto& a : arrows) {
        const cv::Point2d from = at(a.at_mm.x, a.at_mm.y);
        const cv::Point2d to(from.x + a.error_mm.x * magnify * px_per_mm,
                             from.y - a.error_mm.y * magnify * px_per_mm);
        cv::circle(picture, from, 2, cv::Scalar(90, 90, 90), cv::FILLED, cv::LINE_AA);
        cv::arrowedLine(picture, from, to, cv::Scalar(40, 40, 200), 2, cv::LINE_AA, 0, 0.25);
    }
    char text[160];
    cv::putText(picture, title, {12, 28}, cv::FONT_HERSHEY_SIMPLEX, 0.7, cv::Scalar(0, 0, 0), 2,
                cv::LINE_AA);
    std::snprintf(text, sizeof text, "errors x%g (largest %.4f mm), %zu points; x right, y up",
                  magnify, largest, arrows.size());
    cv::putText(picture, text, {12, 54}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(40, 40, 200), 1,
                cv::LINE_AA);
    // A scale bar: the length an error of `bar_mm` draws.
    const double bar_mm = largest > 0 ? std::pow(10.0, std::floor(std::log10(largest))) : 0.1;
    const int bar_px = static_cast<int>(std::lround(bar_mm * magnify * px_per_mm));
    cv::line(picture, {12, kSize - 20}, {12 + bar_px, kSize - 20}, cv::Scalar(40, 40, 200), 3);
    std::snprintf(text, sizeof text, "%g mm of error", bar_mm);
    cv::putText(picture, text, {20 + bar_px, kSize - 14}, cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    return png_of_picture(picture);
}

}  // namespace calbox::firmware
