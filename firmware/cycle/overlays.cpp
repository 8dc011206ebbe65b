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
namespace {

cv::Mat as_mat(const vision::GrayView& v) {
    return {v.height_px, v.width_px, CV_8UC1, const_cast<std::uint8_t*>(v.pixels),
            static_cast<std::size_t>(v.stride_bytes)};
}

// A grid mode's overlay: the marks found (green; those `labelled` says, with their column,row)
// and the extra blobs (orange, twice the size), all on the sheet's surface at height z_mm.
struct GridMark {
    geometry::Point2 measured_mm;
    int column = 0, row = 0;
    bool labelled = false;
};
struct GridMarkStyle {
    int radius_divisor;         // the mark's radius: the picture's width / this (at least 4 px)
    int label_offset_radii;     // the label's start, right of the mark, in radii
    double font_scale_divisor;  // the label's scale: the picture's width / this
};

std::string grid_overlay_png(const vision::GrayView& photo, const std::vector<GridMark>& marks,
                             const std::vector<geometry::Point2>& extra_mm, double z_mm,
                             const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                             const GridMarkStyle& style) {
    cv::Mat picture;
    cv::cvtColor(as_mat(photo), picture, cv::COLOR_GRAY2BGR);
    const int thickness = std::max(1, picture.cols / 1500);
    std::vector<geometry::Point3> points;
    points.reserve(marks.size() + extra_mm.size());
    for (const auto& m : marks) points.push_back({m.measured_mm.x, m.measured_mm.y, z_mm});
    for (const auto& e : extra_mm) points.push_back({e.x, e.y, z_mm});
    const auto px = geometry::project_points(camera, plane.bed_to_camera, points);
    const int radius = std::max(4, picture.cols / style.radius_divisor);
    for (std::size_t i = 0; i < px.size(); ++i) {
        const cv::Point at(cvRound(px[i].x), cvRound(px[i].y));
        const bool mark = i < marks.size();
        cv::circle(picture, at, mark ? radius : 2 * radius,
                   mark ? cv::Scalar(0, 200, 0) : cv::Scalar(0, 140, 255), thickness);
        if (mark && marks[i].labelled) {
            const std::string label =
                std::to_string(marks[i].column) + "," + std::to_string(marks[i].row);
            cv::putText(picture, label, at + cv::Point(style.label_offset_radii * radius, -radius),
                        cv::FONT_HERSHEY_SIMPLEX, picture.cols / style.font_scale_divisor,
                        cv::Scalar(255, 0, 0), thickness);
        }
    }
    return png_of_picture(picture);
}

}  // namespace

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

std::string delta_overlay_png(const vision::GrayView& photo,
                              const modes::DeltaMeasurement& measured,
                              const geometry::CameraModel& camera,
                              const geometry::BedPlane& plane) {
    const auto& fs = measured.features;
    const auto placed = modes::placement_errors(fs);
    cv::Mat picture;
    cv::cvtColor(as_mat(photo), picture, cv::COLOR_GRAY2BGR);
    const int thickness = std::max(1, picture.cols / 1000);
    std::map<std::string, geometry::Point2> pixel;
    for (const auto& m : measured.frames.front()) {
        std::vector<cv::Point> outline;
        for (int k = 0; k < 4; ++k) {
            const auto& p = m.corners[static_cast<std::size_t>(k)];
            outline.emplace_back(cvRound(p.x), cvRound(p.y));
            pixel[modes::corner_feature_id(m.id, k)] = p;
        }
        cv::polylines(picture, outline, true, cv::Scalar(0, 200, 0), thickness);
    }
    // Magnified so that the largest error is drawn about 15 mm long on the bed (a nice
    // factor from 10 to 1000, printed on the picture); each arrow is projected through the
    // camera, so it points the way the error does whatever the camera's roll.
    const auto& errors = placed.error_mm;
    const double largest = placed.largest_mm;
    double gain = 10;
    for (const double nice : {20.0, 50.0, 100.0, 200.0, 500.0, 1000.0})
        if (nice * largest <= 15) gain = nice;
    // Each drawn corner's arrow: its measured point and its magnified error, on the bed.
    std::vector<cv::Point2d> from_px;
    std::vector<geometry::Point3> arrow_ends;
    for (std::size_t i = 0; i < fs.size(); ++i) {
        const auto it = pixel.find(fs[i].id);
        if (it == pixel.end()) continue;
        const auto& f = fs[i];
        from_px.emplace_back(it->second.x, it->second.y);
        arrow_ends.push_back({f.measured_mm.x, f.measured_mm.y, f.seen_at_height_mm});
        arrow_ends.push_back({f.measured_mm.x + gain * errors[i].x,
                              f.measured_mm.y + gain * errors[i].y, f.seen_at_height_mm});
    }
    const auto ends = geometry::project_points(camera, plane.bed_to_camera, arrow_ends);
    for (std::size_t i = 0; i < from_px.size(); ++i) {
        const auto& tail = ends[2 * i];
        const auto& head = ends[2 * i + 1];
        const cv::Point2d to = from_px[i] + cv::Point2d(head.x - tail.x, head.y - tail.y);
        cv::arrowedLine(picture, cv::Point(cvRound(from_px[i].x), cvRound(from_px[i].y)),
                        cv::Point(cvRound(to.x), cvRound(to.y)), cv::Scalar(0, 0, 255), thickness);
    }
    char legend[120];
    std::snprintf(legend, sizeof legend, "errors x%.0f (largest %.3f mm)", gain, largest);
    cv::putText(picture, legend, {picture.cols / 40, picture.rows / 20}, cv::FONT_HERSHEY_SIMPLEX,
                picture.cols / 1500.0, cv::Scalar(0, 0, 255), thickness);
    // Each bar between its measured end ticks, with its length against the commanded one.
    for (const auto& b : measured.bars) {
        const auto px = geometry::project_points(camera, plane.bed_to_camera,
                                                 {b.ticks_seen_mm[0], b.ticks_seen_mm[1]});
        const cv::Point from(cvRound(px[0].x), cvRound(px[0].y));
        const cv::Point to(cvRound(px[1].x), cvRound(px[1].y));
        cv::line(picture, from, to, cv::Scalar(255, 160, 0), 2 * thickness);
        char label[80];
        std::snprintf(label, sizeof label, "%c %.3f mm (%+.3f)", b.tower, b.measured_mm,
                      b.measured_mm - b.commanded_mm);
        cv::putText(picture, label, (from + to) / 2, cv::FONT_HERSHEY_SIMPLEX,
                    picture.cols / 2000.0, cv::Scalar(255, 160, 0), thickness);
    }
    return png_of_picture(picture);
}

std::string galvo_overlay_png(const vision::GrayView& photo,
                              const modes::GalvoMeasurement& measured,
                              const models::MachineFile& machine,
                              const geometry::CameraModel& camera,
                              const geometry::BedPlane& plane) {
    std::vector<GridMark> marks;
    for (const auto& n : measured.nodes)
        marks.push_back({n.measured_mm, n.index.column, n.index.row,
                         n.index.column % 5 == 0 && n.index.row % 5 == 0});
    return grid_overlay_png(photo, marks, measured.extra_mm, machine.galvo->substrate_height_mm,
                            camera, plane, {300, 1, 4000.0});
}

std::string planar_overlay_png(const vision::GrayView& photo,
                               const modes::PlanarMeasurement& measured,
                               const models::MachineFile& machine,
                               const geometry::CameraModel& camera,
                               const geometry::BedPlane& plane) {
    // The holes are in the machine's frame (y flipped back for a mirrored photo); the picture
    // wants the photo's, in which the extra blobs already are.
    const double flip = measured.mirrored ? -1 : 1;
    std::vector<GridMark> marks;
    for (const auto& h : measured.holes)
        marks.push_back(
            {{h.measured_mm.x, flip * h.measured_mm.y}, h.index.column, h.index.row, h.large});
    return grid_overlay_png(photo, marks, measured.extra_mm, machine.planar->surface_height_mm,
                            camera, plane, {250, 2, 2000.0});
}

}  // namespace calbox::firmware
