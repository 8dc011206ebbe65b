// On-demand soak: N consecutive calibration cycles of the sim board in one process (the
// appliance as calbox run wires it, on the real clock; the sim board's person does what each
// prompt asks and confirms the review), printing open file descriptors and resident memory after
// the first cycle (the set-up done) and at the end, and every 20 cycles. Both should stay flat:
// a descriptor or a buffer that a cycle does not give back shows here. Not a test: it reports.
//   cmake --build build/release --target bench_soak
//   ./build/release/tests/bench/bench_soak [cycles, 200] [scenario,
//   tests/scenarios/planar_small.toml]
#include <malloc.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "drivers/timerfd_clock.hpp"
#include "firmware/app/sim_appliance.hpp"
#include "firmware/app/sim_operator.hpp"
#include "tests/bench/bench_support.hpp"

using namespace calbox;

namespace {

int open_descriptors() {
    int n = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) ++n;
    return n - 1;  // the iterator's own
}

long resident_kb() {
    std::ifstream status("/proc/self/status");
    std::string key;
    while (status >> key) {
        if (key == "VmRSS:") {
            long kb = 0;
            status >> kb;
            return kb;
        }
        status.ignore(4096, '\n');
    }
    return -1;
}

// The heap's bytes in use (not what the allocator holds for reuse): a leak grows this; a heap
// that only fragments grows the resident memory but not this.
long heap_in_use_kb() {
    const auto info = mallinfo2();
    return static_cast<long>((info.uordblks + info.hblkhd) / 1024);
}

}  // namespace

int main(int argc, char** argv) {
    const int cycles = argc > 1 ? std::atoi(argv[1]) : 200;
    const std::string scenario =
        argc > 2 ? argv[2] : std::string(CALBOX_SOURCE_DIR) + "/tests/scenarios/planar_small.toml";
    char pattern[] = "/tmp/calbox-soak-XXXXXX";
    const std::filesystem::path dir = ::mkdtemp(pattern);
    drivers::TimerfdClock clock;
    firmware::CycleSettings settings;
    settings.records.keep_cycles = 5;  // the records' pruning is part of what runs
    firmware::SimAppliance box({scenario, dir, 115200}, clock, {}, settings,
                               [](const std::string&) {});
    int completed = 0, failed = 0;
    int fds_after_first = 0;
    long rss_after_first = 0;
    const auto start = std::chrono::steady_clock::now();
    const auto operator_acts = box.cycle.subscribe(
        {[&box](firmware::Prompt p, int step) {
             firmware::act_on_prompt(*box.board.bench, *box.board.lines, p, step, true);
         },
         {},
         {},
         {},
         {}});
    const auto counting =
        box.cycle.subscribe({{},
                             {},
                             [&](bool ok) {
                                 ok ? ++completed : ++failed;
                                 const int done = completed + failed;
                                 if (done == 1) {
                                     fds_after_first = open_descriptors();
                                     rss_after_first = resident_kb();
                                 }
                                 if (done == 1 || done % 20 == 0 || done == cycles)
                                     std::printf(
                                         "cycle %3d: %d open descriptors, %ld kB resident, %ld kB "
                                         "heap in use, %.0f s\n",
                                         done, open_descriptors(), resident_kb(), heap_in_use_kb(),
                                         bench::seconds_since(start));
                                 std::fflush(stdout);
                                 if (done >= cycles) {
                                     box.loop.stop();
                                     return;
                                 }
                                 box.board.lines->press(std::chrono::milliseconds(100));
                             },
                             {},
                             {}});
    box.board.lines->press(std::chrono::milliseconds(100));
    box.loop.run();
    std::printf(
        "%d cycles (%d completed, %d failed) in %.0f s; descriptors %d -> %d, resident "
        "%ld -> %ld kB after the first cycle\n",
        completed + failed, completed, failed, bench::seconds_since(start), fds_after_first,
        open_descriptors(), rss_after_first, resident_kb());
    std::filesystem::remove_all(dir);
    return failed == 0 ? 0 : 1;
}
