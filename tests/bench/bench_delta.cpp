// On-demand benchmark: time and peak memory to measure one 4056x3040 photo of the printed delta
// target and to solve. Not a test: it reports numbers. The twin prints and renders the photo in a
// child process, so that the peak memory reported is the box's work alone (loading the photo,
// measuring, solving).
//   cmake --build build/release --target bench_delta && ./build/release/tests/bench/bench_delta

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "board/sim/camera_reference.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenes.hpp"
#include "core/modes/delta.hpp"
#include "tests/bench/bench_support.hpp"
#include "tests/bench/seed_pipelines.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;
using bench::peak_rss_mb;
using bench::seconds_since;

int main() {
    auto machine = models::parse_machine_file(
        "[machine]\nkind = \"delta\"\nbed_radius_mm = 85.0\n[delta]\ndiagonal_rod_mm = "
        "250.0\nradius_mm = 140.0\n",
        "bench");
    sim::DeltaParams truth;
    truth.diagonal_rod_mm = 251;
    sim::DeltaTwin twin(truth, sim::DeltaParams{});
    twin.zero_height_at_centre();
    const auto target = targets::make_delta_target(machine);
    const sim::CameraIntrinsics camera = test::hq_camera();
    const sim::Pose pose = sim::look_at_pose({0, -35, 400}, {0, 0, 0}, 0);
    // The twin prints and photographs in a child process: the peak memory below is the box's.
    const auto photo_file = std::filesystem::temp_directory_path() /
                            ("calbox_bench_delta_" + std::to_string(::getpid()) + ".png");
    const bool rendered = bench::in_child_process([&] {
        sim::DeltaParams truth;
        truth.diagonal_rod_mm = 251;
        sim::DeltaTwin twin(truth, sim::DeltaParams{});
        twin.zero_height_at_centre();
        auto strokes = test::print_on_twin(twin, jobs::write_gcode(target.job, machine, "bench"));
        sim::PhotoSettings photo;
        photo.blur_sigma_px = 0.7;
        photo.noise_sigma_dn = 2;
        const auto start = std::chrono::steady_clock::now();
        const auto image = test::photo_of_print(camera, pose, std::move(strokes), photo);
        std::printf("render 4056x3040 (twin, not the box's work): %.2f s\n", seconds_since(start));
        cv::imwrite(photo_file.string(), cv::Mat(image.height_px, image.width_px, CV_8UC1,
                                                 const_cast<std::uint8_t*>(image.pixels.data())));
    });
    if (!rendered) {
        std::fprintf(stderr, "bench_delta: the twin's part failed\n");
        return 1;
    }
    const geometry::CameraModel model = test::as_core(camera);
    geometry::BedPlane plane;  // the true bed pose
    const auto r = sim::vector_from_rotation(pose.rotation);
    plane.bed_to_camera.rvec = {r.x, r.y, r.z};
    plane.bed_to_camera.tvec_mm = {pose.translation_mm.x, pose.translation_mm.y,
                                   pose.translation_mm.z};
    const long before = peak_rss_mb();
    auto start = std::chrono::steady_clock::now();
    const cv::Mat gray = cv::imread(photo_file.string(), cv::IMREAD_GRAYSCALE);
    std::filesystem::remove(photo_file);
    std::printf("load the photo (PNG): %.3f s\n", seconds_since(start));
    const vision::GrayView view{gray.data, gray.cols, gray.rows, static_cast<int>(gray.step)};
    constexpr int kRuns = 3;
    start = std::chrono::steady_clock::now();
    modes::DeltaMeasurement measured;
    for (int i = 0; i < kRuns; ++i) {
        measured = modes::measure_delta(machine, model, plane, {view});
    }
    std::printf("measure one 4056x3040 frame: %.3f s (mean of %d), %zu corners\n",
                seconds_since(start) / kRuns, kRuns, measured.features.size());
    // Against the seed's pipeline on the same frame, interleaved.
    const auto undistort = bench::seed_undistort_maps(model);
    const auto& square = target.markers.front().corners_mm;
    const double marker_mm = std::hypot(square[1].x - square[0].x, square[1].y - square[0].y);
    int seed_found = 0;
    const auto t = bench::interleaved_medians(
        [&] { measured = modes::measure_delta(machine, model, plane, {view}); },
        [&] { seed_found = bench::seed_delta_frame(gray, undistort, marker_mm); }, 7);
    std::printf("the seed's pipeline (REFERENCE.md 1) on the same frame: %.3f s (%d bar ends)\n",
                t.seed_s, seed_found);
    std::printf("ledger delta_frame_s %.4f\nledger delta_seed_frame_s %.4f\n", t.box_s, t.seed_s);
    std::printf("ledger delta_frame_ratio %.3f\n", t.ratio());
    start = std::chrono::steady_clock::now();
    const auto fit = solve::fit_delta(machine, measured.features, {});
    std::printf("solve: %.3f s, fit RMS %.4f mm\n", seconds_since(start), fit.fitted.fit_rms_mm);
    std::printf(
        "peak resident memory of the box's work: %ld MB (%ld MB before loading the photo)\n",
        peak_rss_mb(), before);
    std::printf("ledger delta_box_peak_mb %ld\n", peak_rss_mb());
    return 0;
}
