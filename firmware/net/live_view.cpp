#include "firmware/net/live_view.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/geometry/camera_model.hpp"
#include "core/vision/exposure.hpp"
#include "core/vision/image_codec.hpp"

namespace calbox::firmware {
namespace {

cv::Mat gray_of(const hal::Frame& frame) {
    if (frame.format == hal::PixelFormat::gray8) {
        return cv::Mat(frame.height_px, frame.width_px, CV_8UC1,
                       const_cast<std::uint8_t*>(frame.pixels.data()),
                       static_cast<std::size_t>(frame.stride_bytes));
    }
    const cv::Mat rgb(frame.height_px, frame.width_px, CV_8UC3,
                      const_cast<std::uint8_t*>(frame.pixels.data()),
                      static_cast<std::size_t>(frame.stride_bytes));
    cv::Mat gray;
    cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
    return gray;
}

double laplacian_variance(const cv::Mat& gray) {
    // The middle half each way: the bed, where focus matters, not the box's own frame.
    const cv::Rect middle(gray.cols / 4, gray.rows / 4, std::max(1, gray.cols / 2),
                          std::max(1, gray.rows / 2));
    cv::Mat lap;
    cv::Laplacian(gray(middle), lap, CV_32F);
    cv::Scalar mean, stddev;
    cv::meanStdDev(lap, mean, stddev);
    return stddev[0] * stddev[0];
}

// The bed's outline in the bed frame, centred where the camera's axis meets the bed: where the
// bed should lie for the box to see it whole.
std::vector<geometry::Point3> bed_outline(const LiveGuide& g) {
    cv::Matx33d r;
    cv::Rodrigues(cv::Vec3d(g.plane->bed_to_camera.rvec[0], g.plane->bed_to_camera.rvec[1],
                            g.plane->bed_to_camera.rvec[2]),
                  r);
    const cv::Vec3d t(g.plane->bed_to_camera.tvec_mm[0], g.plane->bed_to_camera.tvec_mm[1],
                      g.plane->bed_to_camera.tvec_mm[2]);
    const cv::Vec3d centre = -(r.t() * t);              // the camera in the bed frame
    const cv::Vec3d axis = r.t() * cv::Vec3d(0, 0, 1);  // its optical axis there
    std::vector<geometry::Point3> out;
    if (std::abs(axis[2]) < 1e-6) return out;  // looking along the bed: no point to centre on
    const double s = -centre[2] / axis[2];
    const double cx = centre[0] + s * axis[0], cy = centre[1] + s * axis[1];
    if (g.bed_radius_mm > 0) {
        for (int i = 0; i <= 72; ++i) {
            const double a = 2 * M_PI * i / 72;
            out.push_back(
                {cx + g.bed_radius_mm * std::cos(a), cy + g.bed_radius_mm * std::sin(a), 0});
        }
    } else {
        const double hx = g.bed_size_x_mm / 2, hy = g.bed_size_y_mm / 2;
        for (int i = 0; i <= 4; ++i) {
            const int c = i % 4;
            out.push_back({cx + ((c == 1 || c == 2) ? hx : -hx), cy + (c >= 2 ? hy : -hy), 0});
        }
    }
    return out;
}

// What a guide draws, as text to compare by: the camera and the plane (none, or a set-up that
// found them again), the bed, and the views so far (each view, once taken, stays as it is).
std::string what_guide_shows(const LiveGuide& guide) {
    std::string shown;
    char part[160];
    if (guide.camera) {
        const auto& c = *guide.camera;
        std::snprintf(part, sizeof part, "camera %d %.9g %.9g %.9g %.9g %.9g;",
                      static_cast<int>(c.model), c.fx(), c.fy(), c.cx(), c.cy(), c.rms_px);
        shown += part;
    }
    if (guide.plane) {
        const auto& p = guide.plane->bed_to_camera;
        std::snprintf(part, sizeof part, "plane %.9g %.9g %.9g %.9g %.9g %.9g %.9g;", p.rvec[0],
                      p.rvec[1], p.rvec[2], p.tvec_mm[0], p.tvec_mm[1], p.tvec_mm[2],
                      guide.plane->board_thickness_mm);
        shown += part;
    }
    std::snprintf(part, sizeof part, "bed %.9g %.9g %.9g; views %zu %.9g", guide.bed_radius_mm,
                  guide.bed_size_x_mm, guide.bed_size_y_mm, guide.views.size(), guide.coverage);
    return shown + part;
}

}  // namespace

namespace {

// A photo's pixel in the view drawn `scale` times its size.
cv::Point scaled_px(const geometry::Point2& p, double scale) {
    return cv::Point(static_cast<int>(std::lround(p.x * scale)),
                     static_cast<int>(std::lround(p.y * scale)));
}

// The set-up's coverage: each view's board, filled faintly, so the gaps show.
template <class At>
void draw_coverage(cv::Mat& view, const LiveGuide& guide, const At& at) {
    cv::Mat covered = view.clone();
    for (const auto& corners : guide.views) {
        std::vector<cv::Point> pts;
        pts.reserve(corners.size());
        for (const auto& p : corners) pts.push_back(at(p));
        if (pts.size() < 3) continue;
        std::vector<cv::Point> hull;
        cv::convexHull(pts, hull);
        cv::fillConvexPoly(covered, hull, cv::Scalar(0, 200, 0));
        cv::polylines(view, std::vector<std::vector<cv::Point>>{hull}, true, cv::Scalar(0, 160, 0),
                      1, cv::LINE_AA);
    }
    if (!guide.views.empty()) cv::addWeighted(covered, 0.3, view, 0.7, 0, view);
}

}  // namespace

LiveImage live_view(const hal::Frame& frame, const LiveGuide& guide, int max_width_px) {
    if (frame.width_px <= 0 || frame.height_px <= 0 || frame.pixels.empty())
        throw std::invalid_argument("live view: an empty frame");
    const cv::Mat gray = gray_of(frame);
    LiveImage image;
    image.sharpness = laplacian_variance(gray);
    image.sequence = frame.metadata.sequence;
    const double scale = std::min(1.0, static_cast<double>(max_width_px) / frame.width_px);
    cv::Mat small;
    cv::resize(gray, small, cv::Size(), scale, scale, cv::INTER_AREA);
    cv::Mat view;
    cv::cvtColor(small, view, cv::COLOR_GRAY2BGR);
    // Clipped white, where nothing can be measured and a board's squares wash out (the
    // metering's level), and black (a mark's contrast there is under the noise of a dim sensor).
    constexpr int kBlackToDn = 8;
    const cv::Mat clipped = small >= vision::MeteringLimits{}.clipped_from_dn,
                  black = small <= kBlackToDn;
    image.clipped_share = cv::countNonZero(clipped) / static_cast<double>(small.total());
    image.black_share = cv::countNonZero(black) / static_cast<double>(small.total());
    view.setTo(cv::Scalar(40, 40, 255), clipped);
    view.setTo(cv::Scalar(255, 120, 0), black);
    const auto at = [scale](const geometry::Point2& p) { return scaled_px(p, scale); };
    draw_coverage(view, guide, at);
    const int font = cv::FONT_HERSHEY_SIMPLEX;
    const double text_scale = std::max(0.4, view.cols / 1200.0);
    int line = 1;
    const auto text = [&](const std::string& s, const cv::Scalar& colour) {
        const cv::Point org(8, static_cast<int>(line++ * 26 * text_scale / 0.6));
        cv::putText(view, s, org, font, text_scale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
        cv::putText(view, s, org, font, text_scale, colour, 1, cv::LINE_AA);
    };
    if (guide.camera && guide.plane) {
        const auto outline = bed_outline(guide);
        if (!outline.empty()) {
            const auto pixels =
                geometry::project_points(*guide.camera, guide.plane->bed_to_camera, outline);
            std::vector<cv::Point> pts;
            pts.reserve(pixels.size());
            for (const auto& p : pixels) pts.push_back(at(p));
            cv::polylines(view, std::vector<std::vector<cv::Point>>{pts}, false,
                          cv::Scalar(0, 200, 255), 2, cv::LINE_AA);
        }
        text("bed outline (orange): the machine's bed belongs inside it", cv::Scalar(0, 200, 255));
    } else {
        text("bed outline after the set-up (camera and plane)", cv::Scalar(200, 200, 200));
    }
    // A person can fix what a few per cent of the frame shows; less is a speck or a screw head.
    constexpr double kWorthSaying = 0.01;
    if (image.clipped_share >= kWorthSaying)
        text("clipped white " + std::to_string(std::lround(100 * image.clipped_share)) +
                 " % (red): tilt the board or diffuse the lamp's light",
             cv::Scalar(40, 40, 255));
    if (image.black_share >= kWorthSaying)
        text("black " + std::to_string(std::lround(100 * image.black_share)) +
                 " % (blue): more light there",
             cv::Scalar(255, 120, 0));
    char figures[96];
    std::snprintf(figures, sizeof figures, "sharpness %.0f   set-up coverage %.0f %%",
                  image.sharpness, 100 * guide.coverage);
    text(figures, cv::Scalar(255, 255, 255));
    const auto jpeg = vision::jpeg_bytes(
        {view.data, view.cols, view.rows, static_cast<int>(view.step[0]), view.channels()}, 80);
    image.jpeg.assign(jpeg.begin(), jpeg.end());
    image.width_px = view.cols;
    image.height_px = view.rows;
    return image;
}

void LatestFrame::put(const hal::Frame& frame) {
    // Copied outside the lock: a viewer reading the last frame is not held up by the copy.
    auto fresh = std::make_shared<hal::Frame>(frame);
    {
        const std::lock_guard lock(mutex_);
        fresh->metadata.sequence = ++count_;
        frame_ = std::move(fresh);
    }
    arrived_.notify_all();
}

void LatestFrame::wait_past(std::uint64_t after, std::chrono::milliseconds within) {
    std::unique_lock lock(mutex_);
    arrived_.wait_for(lock, within, [&] { return count_ > after; });
}

std::shared_ptr<const hal::Frame> LatestFrame::newest() {
    const std::lock_guard lock(mutex_);
    return frame_;
}

std::shared_ptr<const LiveImage> SharedLiveView::of_newest(LatestFrame& frames,
                                                           const LiveGuide& guide,
                                                           int max_width_px) {
    const std::string shown = what_guide_shows(guide);
    const std::lock_guard lock(mutex_);
    // Taken under the lock and dropped with it: the viewers queued here hold no frame.
    const auto frame = frames.newest();
    if (!frame) return nullptr;
    if (!newest_ || newest_->sequence != frame->metadata.sequence || drawn_guide_ != shown) {
        newest_ = std::make_shared<const LiveImage>(live_view(*frame, guide, max_width_px));
        drawn_guide_ = shown;
    }
    return newest_;
}

}  // namespace calbox::firmware
