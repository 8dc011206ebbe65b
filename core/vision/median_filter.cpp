#include "core/vision/median_filter.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <utility>
#include <vector>

namespace calbox::vision {
namespace {

constexpr std::size_t kLargestPatchPx = std::size_t{256} * 256;

// Which of a compare-exchange's two results a later step reads.
enum class Kept : std::uint8_t { both, low, high };

struct CompareExchange {
    std::uint8_t low_wire = 0, high_wire = 0;
    Kept kept = Kept::both;
};

// A selection network for the middle of `inputs` values (at most 32): Batcher's odd-even merge
// sort on 32 wires, less every exchange with a wire past the inputs (the missing values count
// as the largest, so those exchanges never swap) and every exchange the middle wire does not
// depend on, each kept one computing only the results that are read later.
std::vector<CompareExchange> middle_of(int inputs) {
    constexpr int kWires = 32;
    std::vector<std::pair<int, int>> sorting;
    for (int p = 1; p < kWires; p *= 2)
        for (int k = p; k >= 1; k /= 2)
            for (int j = k % p; j + k < kWires; j += 2 * k)
                for (int i = 0; i < k && i + j + k < inputs; ++i)
                    if ((i + j) / (2 * p) == (i + j + k) / (2 * p))
                        sorting.emplace_back(i + j, i + j + k);
    std::array<bool, kWires> read_later{};
    read_later[static_cast<std::size_t>(inputs / 2)] = true;
    std::vector<CompareExchange> kept;
    for (auto it = sorting.rbegin(); it != sorting.rend(); ++it) {
        const auto a = static_cast<std::size_t>(it->first),
                   b = static_cast<std::size_t>(it->second);
        if (!read_later[a] && !read_later[b]) continue;
        const Kept which = read_later[a] && read_later[b] ? Kept::both
                           : read_later[a]                ? Kept::low
                                                          : Kept::high;
        kept.push_back({static_cast<std::uint8_t>(a), static_cast<std::uint8_t>(b), which});
        read_later[a] = read_later[b] = true;
    }
    std::reverse(kept.begin(), kept.end());
    return kept;
}

// The network run across `Width` pixels at once: each exchange a min and a max over the run, a
// loop of fixed length that the compiler turns into vector code.
template <int Width, std::size_t Wires, std::size_t Run>
void run_network(std::array<std::array<std::uint8_t, Run>, Wires>& wire,
                 const std::vector<CompareExchange>& network) {
    for (const CompareExchange& k : network) {
        std::uint8_t* __restrict a = wire[k.low_wire].data();
        std::uint8_t* __restrict b = wire[k.high_wire].data();
        switch (k.kept) {
            case Kept::both:
                for (int i = 0; i < Width; ++i) {
                    const std::uint8_t u = a[i], v = b[i];
                    a[i] = u < v ? u : v;
                    b[i] = u < v ? v : u;
                }
                break;
            case Kept::low:
                for (int i = 0; i < Width; ++i) a[i] = a[i] < b[i] ? a[i] : b[i];
                break;
            case Kept::high:
                for (int i = 0; i < Width; ++i) b[i] = a[i] < b[i] ? b[i] : a[i];
                break;
        }
    }
}

}  // namespace

cv::Mat median_filtered(const cv::Mat& image, int kernel_px) {
    if (image.type() != CV_8UC1 || image.empty())
        throw std::invalid_argument("a median filter needs an 8-bit grey image");
    if (kernel_px != 1 && kernel_px != 3 && kernel_px != 5)
        throw std::invalid_argument("a median filter of " + std::to_string(kernel_px) +
                                    " pixels: 1, 3 or 5");
    // A whole photo is OpenCV's: its threads and its per-column histograms win over a wide image
    // (a 12 MP 5 x 5 in 20 ms on two cores, against 97 ms here); a mark's patch is this network's.
    if (kernel_px == 1 || image.total() > kLargestPatchPx) {
        cv::Mat out;
        cv::medianBlur(image, out, kernel_px);
        return out;
    }
    static const std::vector<CompareExchange> three = middle_of(9), five = middle_of(25);
    const auto& network = kernel_px == 3 ? three : five;
    const int reach = kernel_px / 2, inputs = kernel_px * kernel_px;
    // Every value of a run of pixels on a wire of its own, the network run across the run. The
    // border is a run wider on the right than the filter needs, so that each wire is filled by a
    // copy of the run's fixed width (a copy of a row's own width was a call to memcpy for each
    // wire of each run, more than the network's work on a mark's patch), and a row's last run is
    // the narrowest of 16, 32 or 64 that holds it (a patch some 80 pixels wide spent a third of a
    // fixed 64's work on its second run's empty tail).
    constexpr int kRun = 64;
    cv::Mat padded;
    cv::copyMakeBorder(image, padded, reach, reach, reach, reach + kRun,
                       cv::BORDER_REPLICATE | cv::BORDER_ISOLATED);
    cv::Mat out(image.size(), CV_8UC1);
    alignas(64) std::array<std::array<std::uint8_t, kRun>, 25> wire{};
    for (int y = 0; y < image.rows; ++y)
        for (int x0 = 0; x0 < image.cols; x0 += kRun) {
            const int n = std::min(kRun, image.cols - x0);
            std::size_t w = 0;
            for (int r = 0; r < kernel_px; ++r)
                for (int c = 0; c < kernel_px; ++c)
                    std::memcpy(wire[w++].data(), padded.ptr<std::uint8_t>(y + r) + x0 + c, kRun);
            if (n <= 16)
                run_network<16>(wire, network);
            else if (n <= 32)
                run_network<32>(wire, network);
            else
                run_network<kRun>(wire, network);
            std::memcpy(out.ptr<std::uint8_t>(y) + x0,
                        wire[static_cast<std::size_t>(inputs / 2)].data(),
                        static_cast<std::size_t>(n));
        }
    return out;
}

}  // namespace calbox::vision
