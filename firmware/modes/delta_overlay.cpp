// The delta's overlay: its markers, their corners' errors and its bars, drawn on the photo.
#include <algorithm>
#include <cstdio>
#include <map>
#include <opencv2/imgproc.hpp>

#include "core/geometry/camera_model.hpp"
#include "firmware/cycle/png_picture.hpp"
#include "firmware/modes/delta_mode.hpp"

namespace calbox::firmware {

std::string delta_overlay_png(const vision::GrayView& photo,
                              const modes::DeltaMeasurement& measured,
                              const geometry::CameraModel& camera,
                              const geometry::BedPlane& plane) {
    const auto& fs = measured.features;
    const auto placed = modes::placement_errors(fs);
    OverlayCanvas canvas = overlay_canvas_of(photo);
    const int thickness = canvas.size(std::max(1, photo.width_px / 1000));
    std::map<std::string, geometry::Point2> pixel;
    for (const auto& m : measured.frames.front()) {
        std::vector<cv::Point> outline;
        for (int k = 0; k < 4; ++k) {
            const auto& p = m.corners[static_cast<std::size_t>(k)];
            outline.push_back(canvas.at(p.x, p.y));
            pixel[modes::corner_feature_id(m.id, k)] = p;
        }
        cv::polylines(canvas.picture, outline, true, cv::Scalar(0, 200, 0), thickness);
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
        cv::arrowedLine(canvas.picture, canvas.at(from_px[i].x, from_px[i].y),
                        canvas.at(to.x, to.y), cv::Scalar(0, 0, 255), thickness);
    }
    char legend[120];
    std::snprintf(legend, sizeof legend, "errors x%.0f (largest %.3f mm)", gain, largest);
    cv::putText(canvas.picture, legend, canvas.at(photo.width_px / 40, photo.height_px / 20),
                cv::FONT_HERSHEY_SIMPLEX, canvas.font_scale(photo.width_px / 1500.0),
                cv::Scalar(0, 0, 255), thickness);
    // Each bar between its measured end ticks, with its length against the commanded one.
    for (const auto& b : measured.bars) {
        const auto px = geometry::project_points(camera, plane.bed_to_camera,
                                                 {b.ticks_seen_mm[0], b.ticks_seen_mm[1]});
        const cv::Point from = canvas.at(px[0].x, px[0].y);
        const cv::Point to = canvas.at(px[1].x, px[1].y);
        cv::line(canvas.picture, from, to, cv::Scalar(255, 160, 0), 2 * thickness);
        char label[80];
        std::snprintf(label, sizeof label, "%c %.3f mm (%+.3f)", b.tower, b.measured_mm,
                      b.measured_mm - b.commanded_mm);
        cv::putText(canvas.picture, label, (from + to) / 2, cv::FONT_HERSHEY_SIMPLEX,
                    canvas.font_scale(photo.width_px / 2000.0), cv::Scalar(255, 160, 0), thickness);
    }
    return png_of(canvas);
}

}  // namespace calbox::firmware
