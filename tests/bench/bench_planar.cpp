// On-demand benchmark: time and peak memory to measure one 12 MP photo (4056 x 3040, a Raspberry
// Pi HQ-class camera) of a router's drilled 12 x 12 hole grid, to fit the error model, and to
// choose a 24-hole DETMAX design. Not a test: it reports numbers. The twin renders the photo and
// the plane board in a child process, so that the peak memory reported is the box's work alone.
//   cmake --build build/release --target bench_planar && ./build/release/tests/bench/bench_planar
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "core/modes/planar.hpp"
#include "tests/bench/bench_support.hpp"
#include "tests/bench/seed_pipelines.hpp"
#include "tests/support/router_fixtures.hpp"

using namespace calbox;
using bench::peak_rss_mb;
using bench::seconds_since;

namespace {
std::string read(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// The twin's part: the drilled sheet and the plane board photographed, the plane estimated.
void prepare(const std::filesystem::path& dir, const models::MachineFile& machine) {
    const auto bench = test::router_bench(1.0);
    const auto target = targets::make_planar_target(machine);
    const auto start = std::chrono::steady_clock::now();
    const auto photo = test::photo_of_drilled_sheet(bench, sim::random_router_truth(1), target.job);
    std::printf("render %dx%d (twin, not the box's work): %.2f s\n", photo.width_px,
                photo.height_px, seconds_since(start));
    cv::imwrite((dir / "holes.png").string(),
                cv::Mat(photo.height_px, photo.width_px, CV_8UC1,
                        const_cast<std::uint8_t*>(photo.pixels.data())));
    const auto camera = test::as_core(bench.camera);
    std::ofstream(dir / "camera.yaml") << geometry::camera_to_yaml(camera);
    std::ofstream(dir / "plane.yaml") << geometry::plane_to_yaml(test::router_plane(bench));
}
}  // namespace

int main() {
    const auto machine = models::parse_machine_file(test::kRouterMachineToml, "bench");
    const auto dir = std::filesystem::temp_directory_path() /
                     ("calbox_bench_planar_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    if (!bench::in_child_process([&] { prepare(dir, machine); })) {
        std::fprintf(stderr, "bench_planar: the twin's part failed\n");
        return 1;
    }
    const auto camera = geometry::camera_from_yaml(read(dir / "camera.yaml"));
    const auto plane = geometry::plane_from_yaml(read(dir / "plane.yaml"));
    const long before = peak_rss_mb();
    auto start = std::chrono::steady_clock::now();
    const cv::Mat photo = cv::imread((dir / "holes.png").string(), cv::IMREAD_GRAYSCALE);
    std::printf("load the photo (PNG): %.3f s\n", seconds_since(start));
    const vision::GrayView view{photo.data, photo.cols, photo.rows, static_cast<int>(photo.step)};
    constexpr int kRuns = 3;
    modes::PlanarMeasurement measured;
    start = std::chrono::steady_clock::now();
    for (int i = 0; i < kRuns; ++i) measured = modes::measure_planar(machine, camera, plane, view);
    std::printf("measure one %dx%d photo: %.3f s (mean of %d), %zu holes\n", photo.cols, photo.rows,
                seconds_since(start) / kRuns, kRuns, measured.holes.size());
    const auto undistort = bench::seed_undistort_maps(camera);
    int seed_found = 0;
    const auto t = bench::interleaved_medians(
        [&] { measured = modes::measure_planar(machine, camera, plane, view); },
        [&] { seed_found = bench::seed_planar_frame(photo, undistort); }, 7);
    std::printf("the seed's pipeline (REFERENCE.md 2) on the same frame: %.3f s (%d ellipses)\n",
                t.seed_s, seed_found);
    std::printf("ledger planar_frame_s %.4f\nledger planar_seed_frame_s %.4f\n", t.box_s, t.seed_s);
    std::printf("ledger planar_frame_ratio %.3f\n", t.ratio());
    start = std::chrono::steady_clock::now();
    modes::PlanarSolution solution;
    for (int i = 0; i < kRuns; ++i) solution = modes::solve_planar(machine, measured);
    std::printf(
        "error model and firmware settings: %.4f s (mean of %d), error norm %.4f -> "
        "%.4f mm mean at the holes\n",
        seconds_since(start) / kRuns, kRuns, solution.before.mean_mm, solution.after.mean_mm);
    start = std::chrono::steady_clock::now();
    const auto design = modes::planar_design_nodes(machine, 24);
    std::printf("DETMAX design of %zu holes out of 141: %.3f s\n", design.size(),
                seconds_since(start));
    std::printf(
        "peak resident memory of the box's work: %ld MB (%ld MB before loading the photo)\n",
        peak_rss_mb(), before);
    std::printf("ledger planar_box_peak_mb %ld\n", peak_rss_mb());
    std::filesystem::remove_all(dir);
    return 0;
}
