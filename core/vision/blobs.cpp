#include "core/vision/blobs.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace calbox::vision {
namespace {

struct Run {
    int y = 0, x0 = 0, x1 = 0;  // x0..x1 inclusive
};

// The first non-zero byte at or after `x`, or `end`: eight background pixels at a look.
int next_set(const std::uint8_t* row, int x, int end) {
    while (x < end && (x & 7) != 0 && row[x] == 0) ++x;
    while (x + 8 <= end) {
        std::uint64_t word = 0;
        std::memcpy(&word, row + x, sizeof word);
        if (word != 0) break;
        x += 8;
    }
    while (x < end && row[x] == 0) ++x;
    return x;
}

int root_of(std::vector<int>& parent, int i) {
    while (parent[static_cast<std::size_t>(i)] != i) {
        auto& p = parent[static_cast<std::size_t>(i)];
        p = parent[static_cast<std::size_t>(p)];  // halving: the trees stay shallow
        i = p;
    }
    return i;
}

}  // namespace

std::vector<Blob> blobs_of(const cv::Mat& mask) {
    if (mask.type() != CV_8UC1) throw std::invalid_argument("blobs need an 8-bit mask");
    std::vector<Run> runs;
    std::vector<int> parent;
    std::size_t above_begin = 0, above_end = 0;  // the previous row's runs
    for (int y = 0; y < mask.rows; ++y) {
        const auto* row = mask.ptr<std::uint8_t>(y);
        const std::size_t row_begin = runs.size();
        std::size_t a = above_begin;
        for (int x = next_set(row, 0, mask.cols); x < mask.cols; x = next_set(row, x, mask.cols)) {
            Run run{y, x, x};
            while (run.x1 + 1 < mask.cols && row[run.x1 + 1] != 0) ++run.x1;
            x = run.x1 + 1;
            const int index = static_cast<int>(runs.size());
            runs.push_back(run);
            parent.push_back(index);
            // 8-connected: a run above touches this one where it reaches a pixel to either side.
            while (a < above_end && runs[a].x1 < run.x0 - 1) ++a;
            for (std::size_t b = a; b < above_end && runs[b].x0 <= run.x1 + 1; ++b) {
                const int r = root_of(parent, static_cast<int>(b)), s = root_of(parent, index);
                if (r != s) parent[static_cast<std::size_t>(std::max(r, s))] = std::min(r, s);
            }
        }
        above_begin = row_begin;
        above_end = runs.size();
    }
    // The root is each blob's first run: a union keeps the smaller index, the earlier run.
    std::vector<int> blob_of_root(runs.size(), -1);
    std::vector<Blob> blobs;
    std::vector<double> sum_x, sum_y;
    for (std::size_t i = 0; i < runs.size(); ++i) {
        const int root = root_of(parent, static_cast<int>(i));
        int& b = blob_of_root[static_cast<std::size_t>(root)];
        if (b < 0) {
            b = static_cast<int>(blobs.size());
            blobs.emplace_back();
            sum_x.push_back(0);
            sum_y.push_back(0);
        }
        const Run& r = runs[i];
        const long length = r.x1 - r.x0 + 1;
        auto& blob = blobs[static_cast<std::size_t>(b)];
        blob.area_px += length;
        sum_x[static_cast<std::size_t>(b)] +=
            0.5 * static_cast<double>(r.x0 + r.x1) * static_cast<double>(length);
        sum_y[static_cast<std::size_t>(b)] +=
            static_cast<double>(r.y) * static_cast<double>(length);
    }
    for (std::size_t b = 0; b < blobs.size(); ++b) {
        blobs[b].centre_x_px = sum_x[b] / static_cast<double>(blobs[b].area_px);
        blobs[b].centre_y_px = sum_y[b] / static_cast<double>(blobs[b].area_px);
    }
    return blobs;
}

}  // namespace calbox::vision
