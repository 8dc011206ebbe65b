// On-demand benchmark: time and peak memory to measure one 20 MP photo (5496 x 3672, the seed
// paper's camera) of the burned galvo grid and to build the 65 x 65 correction table. Not a test:
// it reports numbers.
//   cmake --build build/release --target bench_galvo && ./build/release/tests/bench/bench_galvo
#include <sys/resource.h>

#include <chrono>
#include <cstdio>

#include "core/modes/galvo.hpp"
#include "tests/support/galvo_fixtures.hpp"

using namespace calbox;

namespace {
long peak_rss_mb() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_maxrss / 1024;
}
double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}
}  // namespace

int main() {
    const auto machine = models::parse_machine_file(test::kGalvoMachineToml, "bench");
    auto truth = sim::random_galvo_truth(1);
    truth.substrate_height_mm = machine.galvo->substrate_height_mm;
    test::GalvoBench bench;
    bench.camera = test::galvo_camera(1.0);
    bench.bed_to_camera = sim::look_at_pose({3, -4, 375}, {0, 0, 0}, 1);
    bench.photo.blur_sigma_px = 0.8;
    bench.photo.noise_sigma_dn = 2;
    const auto target = targets::make_galvo_target(machine);
    auto start = std::chrono::steady_clock::now();
    const auto photo = test::photo_of_burned_grid(
        bench, truth, targets::write_gcode(target.job, machine, "bench"));
    std::printf("render %dx%d (twin, not the box's work): %.2f s\n", photo.width_px,
                photo.height_px, seconds_since(start));
    const auto camera = test::as_core(bench.camera);
    const auto plane = test::plane_from_board(bench, camera);
    const long before = peak_rss_mb();
    constexpr int kRuns = 3;
    modes::GalvoMeasurement measured;
    start = std::chrono::steady_clock::now();
    for (int i = 0; i < kRuns; ++i)
        measured = modes::measure_galvo(machine, camera, plane, test::view_of(photo));
    std::printf("measure one %dx%d photo: %.3f s (mean of %d), %zu marks\n", photo.width_px,
                photo.height_px, seconds_since(start) / kRuns, kRuns, measured.nodes.size());
    start = std::chrono::steady_clock::now();
    modes::GalvoSolution solution;
    for (int i = 0; i < kRuns; ++i) solution = modes::solve_galvo(machine, measured, std::nullopt);
    std::printf("field map and 65 x 65 table: %.3f s (mean of %d), error before %.4f mm mean\n",
                seconds_since(start) / kRuns, kRuns, solution.fit.before.mean_mm);
    std::printf(
        "peak resident memory: %ld MB (%ld MB before measuring, the photo and the twin included)\n",
        peak_rss_mb(), before);
    return 0;
}
