#include "core/vision/local_threshold.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <utility>

#include "core/each_on_all_cores.hpp"

namespace calbox::vision {
namespace {

// out[i] = 255 where a[i] - b[i] >= at_least_dn (as integers), else 0. Written on saturated
// differences, which stay in bytes, so that the loop is vector code: a bound at or below zero is
// the complement of b[i] - a[i] >= 1 - at_least_dn. `out` may be `a` or `b`.
void at_least(const std::uint8_t* a, const std::uint8_t* b, std::uint8_t* out, int n,
              int at_least_dn) {
    const bool complement = at_least_dn <= 0;
    if (complement) {
        std::swap(a, b);
        at_least_dn = 1 - at_least_dn;
    }
    const std::uint8_t yes = complement ? 0 : 255, no = complement ? 255 : 0;
    if (at_least_dn > 255) {
        std::memset(out, no, static_cast<std::size_t>(n));
        return;
    }
    const auto t = static_cast<std::uint8_t>(at_least_dn);
    for (int i = 0; i < n; ++i) {
        const std::uint8_t u = a[i], v = b[i];
        const auto d = static_cast<std::uint8_t>(u > v ? u - v : 0);
        out[i] = d >= t ? yes : no;
    }
}

}  // namespace

void local_threshold(const cv::Mat& image, int block_px, bool dark, double contrast_dn,
                     cv::Mat& out) {
    if (image.type() != CV_8UC1 || image.empty())
        throw std::invalid_argument("a local threshold needs an 8-bit grey image");
    if (block_px < 3 || block_px % 2 == 0)
        throw std::invalid_argument("a local threshold's block of " + std::to_string(block_px) +
                                    " pixels: odd, at least 3");
    if (out.data == image.data) out.release();
    out.create(image.size(), CV_8UC1);
    // OpenCV's rule, in its terms: delta = contrast (dark) or -contrast (light), rounded down for
    // THRESH_BINARY_INV and up for THRESH_BINARY; a dark mark is where src - mean <= -delta, a
    // light one where src - mean > -delta.
    const double delta = dark ? contrast_dn : -contrast_dn;
    const int rounded = static_cast<int>(dark ? std::floor(delta) : std::ceil(delta));
    // As bounds on one difference: a dark mark's mean - src >= delta, a light one's
    // src - mean >= 1 - delta.
    const int bound = dark ? rounded : 1 - rounded;
    // The mean as OpenCV's adaptiveThreshold takes it, in bands of rows on all the cores (its box
    // filter runs on one). Each band's mean is taken on the band and half a block of the image's
    // rows either side, as the whole image's filter reads them, so that a band's rows get the
    // whole image's means; at the image's own top and bottom the band ends where the image does
    // and is replicated as the image's would be.
    const int reach = block_px / 2;
    const int bands = std::clamp(cv::getNumThreads(), 1, std::max(1, image.rows / (4 * reach + 1)));
    each_on_all_cores(static_cast<std::size_t>(bands), [&](std::size_t band) {
        const int first = image.rows * static_cast<int>(band) / bands,
                  end = image.rows * static_cast<int>(band + 1) / bands;
        const int read_first = std::max(0, first - reach),
                  read_end = std::min(image.rows, end + reach);
        cv::Mat mean;
        cv::boxFilter(image.rowRange(read_first, read_end), mean, CV_8U,
                      cv::Size(block_px, block_px), cv::Point(-1, -1), true,
                      cv::BORDER_REPLICATE | cv::BORDER_ISOLATED);
        for (int y = first; y < end; ++y) {
            const std::uint8_t* src = image.ptr<std::uint8_t>(y);
            const std::uint8_t* mean_row = mean.ptr<std::uint8_t>(y - read_first);
            std::uint8_t* mask = out.ptr<std::uint8_t>(y);
            if (dark)
                at_least(mean_row, src, mask, image.cols, bound);
            else
                at_least(src, mean_row, mask, image.cols, bound);
        }
    });
}

}  // namespace calbox::vision
