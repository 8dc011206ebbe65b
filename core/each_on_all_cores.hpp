#pragma once

#include <cstddef>
#include <exception>
#include <opencv2/core/utility.hpp>
#include <vector>

namespace calbox {

// Calls `work(i)` for every i below `count` on OpenCV's worker threads (the cores the box has),
// each call free to write only its own i's result. What a call throws is rethrown here as it was
// thrown, the lowest i's first: OpenCV would turn it into a cv::Exception naming nothing.
template <typename Work>
void each_on_all_cores(std::size_t count, const Work& work) {
    std::vector<std::exception_ptr> failed(count);
    cv::parallel_for_(cv::Range(0, static_cast<int>(count)), [&](const cv::Range& range) {
        for (int i = range.start; i < range.end; ++i) {
            const auto at = static_cast<std::size_t>(i);
            try {
                work(at);
            } catch (...) {
                failed[at] = std::current_exception();
            }
        }
    });
    for (const auto& e : failed)
        if (e) std::rethrow_exception(e);
}

}  // namespace calbox
