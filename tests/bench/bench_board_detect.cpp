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
#include "tests/support/board_views.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;

using test::corner_rms;
using test::render_board_views;

int main(int argc, char** argv) {
    const int count = argc > 1 ? std::atoi(argv[1]) : 4;
    std::printf("rendering %d views of 4056 x 3040 ...\n", count);
    const auto views = render_board_views(count);
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
