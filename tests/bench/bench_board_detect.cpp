// On-demand benchmark: finding the calibration chessboard in 12 MP views (4056 x 3040, the
// Pi HQ camera) as the box's set-up does, against OpenCV's SB detector with its accuracy pass at
// full size (the box's way before). Reports each way's time per view and its corners' RMS from
// the twin's true corner positions. Not a test: it reports numbers.
//   cmake --build build/release --target bench_board_detect
//   ./build/release/tests/bench/bench_board_detect [views]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <opencv2/calib3d.hpp>
#include <random>

#include "board/sim/camera_reference.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenes.hpp"
#include "core/geometry/calibration.hpp"
#include "tests/bench/bench_support.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;

namespace {

struct View {
    sim::GrayImage image;
    std::vector<sim::Vec2> truth;  // OpenCV's corner order
};

// An 11x8 chessboard of 20 mm squares held half a metre from the camera, tilted and turned.
std::vector<View> render_views(int count) {
    const auto camera = test::hq_camera();
    const auto spec = geometry::parse_pattern_spec("chessboard:11x8@20");
    const sim::BoardScene board(spec, 2);
    sim::PhotoSettings photo;
    photo.supersample = 2;
    photo.noise_sigma_dn = 2.0;
    photo.blur_sigma_px = 1.2;  // a 12 MP sensor behind a small lens: about a pixel of blur
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> tilt(-25, 25), shift(-1, 1), distance(430, 560);
    std::vector<View> views;
    while (static_cast<int>(views.size()) < count) {
        sim::Pose pose;
        pose.rotation = sim::rotation_from_vector(
            sim::Vec3{sim::radians(tilt(rng)), sim::radians(tilt(rng)), sim::radians(tilt(rng))});
        const double z = distance(rng);
        pose.translation_mm = sim::Vec3{shift(rng) * z * 0.2, shift(rng) * z * 0.1, z} -
                              pose.rotation * sim::Vec3{100, 70, 0};
        bool inside = true;
        for (const auto& c : {sim::Vec3{-30, -30, 0}, sim::Vec3{230, -30, 0},
                              sim::Vec3{-30, 170, 0}, sim::Vec3{230, 170, 0}}) {
            const auto px = sim::project_point(camera, pose, c);
            inside = inside && px.x > 5 && px.y > 5 && px.x < camera.width_px - 5 &&
                     px.y < camera.height_px - 5;
        }
        if (!inside) continue;
        photo.seed = views.size() + 1;
        View v{sim::render_photo(camera, pose, board, photo), {}};
        for (const auto& f : board.features())
            v.truth.push_back(sim::project_point(camera, pose, f.position_mm));
        views.push_back(std::move(v));
    }
    return views;
}

// RMS from the truth, the corners matched to the nearest true corner (either detector may
// number the board from the other end).
double corner_rms(const std::vector<geometry::Point2>& found, const std::vector<sim::Vec2>& truth) {
    double sum = 0;
    for (const auto& p : found) {
        double best = 1e30;
        for (const auto& t : truth)
            best = std::min(best, std::pow(p.x - t.x, 2) + std::pow(p.y - t.y, 2));
        sum += best;
    }
    return std::sqrt(sum / static_cast<double>(found.size()));
}

}  // namespace

int main(int argc, char** argv) {
    const int count = argc > 1 ? std::atoi(argv[1]) : 4;
    std::printf("rendering %d views of 4056 x 3040 ...\n", count);
    const auto views = render_views(count);
    const auto spec = geometry::parse_pattern_spec("chessboard:11x8@20");
    double old_s = 0, new_s = 0, old_sq = 0, new_sq = 0;
    int old_found = 0, new_found = 0;
    for (const auto& v : views) {
        const cv::Mat gray(v.image.height_px, v.image.width_px, CV_8U,
                           const_cast<std::uint8_t*>(v.image.pixels.data()));
        auto start = std::chrono::steady_clock::now();
        std::vector<cv::Point2f> corners;
        const bool old_ok =
            cv::findChessboardCornersSB(gray, cv::Size(spec.columns, spec.rows), corners,
                                        cv::CALIB_CB_ACCURACY | cv::CALIB_CB_NORMALIZE_IMAGE);
        const double old_t = bench::seconds_since(start);
        start = std::chrono::steady_clock::now();
        const auto found = geometry::find_board(spec, test::view_of(v.image));
        const double new_t = bench::seconds_since(start);
        old_s += old_t;
        new_s += new_t;
        double old_rms = 0, new_rms = 0;
        if (old_ok) {
            std::vector<geometry::Point2> p;
            p.reserve(corners.size());
            for (const auto& c : corners) p.push_back({c.x, c.y});
            old_rms = corner_rms(p, v.truth);
            old_sq += old_rms * old_rms;
            ++old_found;
        }
        if (found) {
            new_rms = corner_rms(found->image_points, v.truth);
            new_sq += new_rms * new_rms;
            ++new_found;
        }
        std::printf(
            "view: SB+accuracy at full size %.2f s, %s %.4f px; the box %.2f s (%s), %s %.4f px\n",
            old_t, old_ok ? "found" : "NOT found", old_rms, new_t,
            found ? found->detector.c_str() : "-", found ? "found" : "NOT found", new_rms);
    }
    std::printf(
        "SB with its accuracy pass at full size: %.2f s per view, corner RMS %.4f px (%d of %d "
        "found)\n",
        old_s / count, old_found ? std::sqrt(old_sq / old_found) : 0.0, old_found, count);
    std::printf(
        "the box (reduced search, full-size refinement): %.2f s per view, corner RMS %.4f px (%d "
        "of %d found)\n",
        new_s / count, new_found ? std::sqrt(new_sq / new_found) : 0.0, new_found, count);
    return 0;
}
