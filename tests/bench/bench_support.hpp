#pragma once
// What the benchmarks report with: peak resident memory and wall time.
#include <sys/resource.h>

#include <chrono>

namespace calbox::bench {

inline long peak_rss_mb() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_maxrss / 1024;
}

inline double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace calbox::bench
