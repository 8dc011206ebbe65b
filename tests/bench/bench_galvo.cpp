// On-demand benchmark: time and peak memory to measure one 20 MP photo (5496 x 3672, the seed
// paper's camera) of the burned galvo grid and to build the 65 x 65 correction table. Not a test:
// it reports numbers. The twin renders the photo and the plane board in a child process, so that
// the peak memory reported is the box's work alone (loading the photo, measuring, solving).
//   cmake --build build/release --target bench_galvo && ./build/release/tests/bench/bench_galvo
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "core/modes/galvo.hpp"
#include "tests/bench/bench_support.hpp"
#include "tests/bench/seed_pipelines.hpp"
#include "tests/support/galvo_fixtures.hpp"

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

// The twin's part: the burned grid and the plane board photographed, the plane estimated.
void prepare(const std::filesystem::path& dir, const models::MachineFile& machine) {
    auto truth = sim::random_galvo_truth(1);
    truth.substrate_height_mm = machine.galvo->substrate_height_mm;
    test::GalvoBench bench;
    bench.camera = test::galvo_camera(1.0);
    bench.bed_to_camera = sim::look_at_pose({3, -4, 375}, {0, 0, 0}, 1);
    bench.photo.blur_sigma_px = 0.8;
    bench.photo.noise_sigma_dn = 2;
    const auto target = targets::make_galvo_target(machine);
    const auto start = std::chrono::steady_clock::now();
    const auto photo =
        test::photo_of_burned_grid(bench, truth, jobs::write_gcode(target.job, machine, "bench"));
    std::printf("render %dx%d (twin, not the box's work): %.2f s\n", photo.width_px,
                photo.height_px, seconds_since(start));
    cv::imwrite((dir / "grid.png").string(),
                cv::Mat(photo.height_px, photo.width_px, CV_8UC1,
                        const_cast<std::uint8_t*>(photo.pixels.data())));
    const auto camera = test::as_core(bench.camera);
    std::ofstream(dir / "camera.yaml") << geometry::camera_to_yaml(camera);
    std::ofstream(dir / "plane.yaml") << geometry::plane_to_yaml(test::plane_from_board(bench));
}
}  // namespace

int main() {
    const auto machine = models::parse_machine_file(test::kGalvoMachineToml, "bench");
    const auto dir = std::filesystem::temp_directory_path() /
                     ("calbox_bench_galvo_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    if (!bench::in_child_process([&] { prepare(dir, machine); })) {
        std::fprintf(stderr, "bench_galvo: the twin's part failed\n");
        return 1;
    }
    const auto camera = geometry::camera_from_yaml(read(dir / "camera.yaml"));
    const auto plane = geometry::plane_from_yaml(read(dir / "plane.yaml"));
    const long before = peak_rss_mb();
    auto start = std::chrono::steady_clock::now();
    const cv::Mat photo = cv::imread((dir / "grid.png").string(), cv::IMREAD_GRAYSCALE);
    std::printf("load the photo (PNG): %.3f s\n", seconds_since(start));
    const vision::GrayView view{photo.data, photo.cols, photo.rows, static_cast<int>(photo.step)};
    constexpr int kRuns = 3;
    modes::GalvoMeasurement measured;
    start = std::chrono::steady_clock::now();
    for (int i = 0; i < kRuns; ++i) measured = modes::measure_galvo(machine, camera, plane, view);
    std::printf("measure one %dx%d photo: %.3f s (mean of %d), %zu marks\n", photo.cols, photo.rows,
                seconds_since(start) / kRuns, kRuns, measured.nodes.size());
    const int grid = targets::make_galvo_target(machine).grid_count;
    int seed_found = 0;
    const auto t = bench::interleaved_medians(
        [&] { measured = modes::measure_galvo(machine, camera, plane, view); },
        [&] {
            seed_found = bench::seed_galvo_frame(photo, {grid, grid}, 40);
        },
        5);
    std::printf("the seed's pipeline (REFERENCE.md 4) on the same frame: %.3f s (%d circles)\n",
                t.seed_s, seed_found);
    std::printf("ledger galvo_frame_s %.4f\nledger galvo_seed_frame_s %.4f\n", t.box_s, t.seed_s);
    std::printf("ledger galvo_frame_ratio %.3f\n", t.ratio());
    start = std::chrono::steady_clock::now();
    modes::GalvoSolution solution;
    for (int i = 0; i < kRuns; ++i) solution = modes::solve_galvo(machine, measured, std::nullopt);
    std::printf("field map and 65 x 65 table: %.3f s (mean of %d), error before %.4f mm mean\n",
                seconds_since(start) / kRuns, kRuns, solution.fit.before.mean_mm);
    std::printf(
        "peak resident memory of the box's work: %ld MB (%ld MB before loading the photo)\n",
        peak_rss_mb(), before);
    std::printf("ledger galvo_box_peak_mb %ld\n", peak_rss_mb());
    std::filesystem::remove_all(dir);
    return 0;
}
