// The fixed-point measurement kernels give the same bits on every architecture the box is built
// for: their outputs on an image made with integer arithmetic only are folded into one digest and
// compared with the value stored here, which the x86-64 and the arm64 (qemu) builds both meet.
// Only integer results and doubles made by one correctly rounded division or addition of them
// take part: GCC contracts a*b+c into a fused multiply-add on arm64 (C++ keeps -ffp-contract=fast),
// so the kernels' double-precision by-products (a spot's elongation and sigma) may differ in
// their last bits between the two and are left out.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "core/median.hpp"
#include "core/vision/blobs.hpp"
#include "core/vision/edge_kernel.hpp"
#include "core/vision/local_threshold.hpp"
#include "core/vision/median_filter.hpp"
#include "core/vision/spots.hpp"

using namespace calbox;

namespace {

constexpr std::size_t kSide = 96;
// A dark disc (radius 12.3 px, edge ramp 2 px wide in squared distance) at (47.37, 51.81) px on a
// bright substrate with +-3 grey levels of hashed noise, all in integers.
constexpr std::int64_t kCentreX_q8 = 12127, kCentreY_q8 = 13263, kRadius_q8 = 3149;

std::uint32_t pixel_hash(std::uint32_t x, std::uint32_t y) {
    std::uint32_t h = x * 0x9E3779B1u ^ (y + 0x7F4A7C15u) * 0x85EBCA77u;
    h ^= h >> 15;
    h *= 0x2C1B3C6Du;
    h ^= h >> 12;
    return h;
}

std::vector<std::uint8_t> integer_disc_image() {
    std::vector<std::uint8_t> pixels(kSide * kSide);
    const std::int64_t outer2 = (kRadius_q8 + 256) * (kRadius_q8 + 256);
    const std::int64_t inner2 = (kRadius_q8 - 256) * (kRadius_q8 - 256);
    for (std::size_t y = 0; y < kSide; ++y)
        for (std::size_t x = 0; x < kSide; ++x) {
            const std::int64_t ex = static_cast<std::int64_t>(x) * 256 - kCentreX_q8;
            const std::int64_t ey = static_cast<std::int64_t>(y) * 256 - kCentreY_q8;
            const std::int64_t d2 = ex * ex + ey * ey;
            const std::int64_t dark = std::clamp<std::int64_t>(outer2 - d2, 0, outer2 - inner2);
            const std::int64_t level = 200 - 170 * dark / (outer2 - inner2);
            const std::int64_t noise =
                static_cast<std::int64_t>(
                    pixel_hash(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y)) % 7) -
                3;
            pixels[y * kSide + x] =
                static_cast<std::uint8_t>(std::clamp<std::int64_t>(level + noise, 0, 255));
        }
    return pixels;
}

struct Digest {
    std::uint64_t value = 0xCBF29CE484222325ull;  // FNV-1a, 64 bits
    void add(std::uint64_t word) {
        for (int byte = 0; byte < 8; ++byte) {
            value ^= (word >> (8 * byte)) & 0xFFu;
            value *= 0x100000001B3ull;
        }
    }
    void add(double v) { add(std::bit_cast<std::uint64_t>(v)); }
};

// Eight directions of 1/8 px steps in Q16: the axes, and 3-4-5 triangles in between.
constexpr std::array<std::array<std::int64_t, 2>, 8> kSteps_q16{{{8192, 0},
                                                                 {4915, 6554},
                                                                 {0, 8192},
                                                                 {-6554, 4915},
                                                                 {-8192, 0},
                                                                 {-4915, -6554},
                                                                 {0, -8192},
                                                                 {6554, -4915}}};

}  // namespace

TEST_GROUP(FixedPointKernels) {
    std::vector<std::uint8_t> pixels = integer_disc_image();
    vision::GrayView view{pixels.data(), static_cast<int>(kSide), static_cast<int>(kSide),
                          static_cast<int>(kSide)};
};

// Radial profiles from near the disc's centre outwards, both directions of step asked for, and
// the moment kernel on windows placed at sub-pixel offsets: every sample, edge and centroid.
TEST(FixedPointKernels, give_the_stored_bits_on_every_architecture) {
    Digest digest;
    constexpr int kCount = 160;  // 20 px: past the disc's edge (12.3 px) on every ray
    std::array<std::int32_t, kCount> profile{};
    int rising_edges = 0;
    double worst_edge_error_px = 0;
    for (int k = 0; k < 200; ++k) {
        // Starts scattered over +-1 px around the centre by an integer sequence.
        const std::int64_t x0 = kCentreX_q8 * 256 + (k * 40503 % 131072) - 65536;
        const std::int64_t y0 = kCentreY_q8 * 256 + (k * 77201 % 131072) - 65536;
        const auto& step = kSteps_q16[static_cast<std::size_t>(k % 8)];
        CHECK(vision::sample_profile_q8(view, x0, y0, step[0], step[1], kCount, profile.data()));
        for (const std::int32_t v : profile) digest.add(static_cast<std::uint64_t>(v));
        const auto rising = vision::step_edge_q16(profile.data(), kCount, true);
        const auto falling = vision::step_edge_q16(profile.data(), kCount, false);
        digest.add(static_cast<std::uint64_t>(rising.value_or(-1)));
        digest.add(static_cast<std::uint64_t>(falling.value_or(-1)));
        if (!rising) continue;
        ++rising_edges;
        // Where the edge is in the image: half-dark at sqrt(r^2 + 1) = 12.34 px from the centre.
        const double x =
            vision::from_q16(x0 + *rising * step[0] / vision::kQ16) - kCentreX_q8 / 256.0;
        const double y =
            vision::from_q16(y0 + *rising * step[1] / vision::kQ16) - kCentreY_q8 / 256.0;
        worst_edge_error_px = std::max(worst_edge_error_px, std::abs(std::hypot(x, y) - 12.34));
    }
    CHECK_EQUAL(200, rising_edges);
    // The sanity of what is hashed: the kernel finds the disc's edge where it was drawn.
    CHECK(worst_edge_error_px < 0.15);

    for (int k = 0; k < 40; ++k) {
        vision::MomentWindow window;
        window.centre_px = {47.0 + k * 0.0625, 52.5 - k * 0.03125};
        window.radius_px = 16.0 + (k % 5) * 0.25;
        window.substrate_dn = 200;
        window.mark_dn = 30;
        window.noise_dn = 2;
        const auto spot = vision::measure_spot_q16(view, window);
        digest.add(spot.centre_px.x);
        digest.add(spot.centre_px.y);
        digest.add(spot.area_px);
        DOUBLES_EQUAL(kCentreX_q8 / 256.0, spot.centre_px.x, 0.05);
        DOUBLES_EQUAL(kCentreY_q8 / 256.0, spot.centre_px.y, 0.05);
    }

    constexpr std::uint64_t kStoredDigest = 0x2C7434720370F73Aull;
    if (digest.value != kStoredDigest)
        std::fprintf(stderr, "fixed-point kernels' digest: 0x%016llX\n",
                     static_cast<unsigned long long>(digest.value));
    CHECK_EQUAL(kStoredDigest, digest.value);
}

// The blobs are OpenCV's 8-connected components, area and centroid to the last bit, in the raster
// order of their first pixels: random masks from sparse specks to nearly full (rings, diagonal
// chains that join only through a corner, runs to the image's edges, widths that are not a
// multiple of the eight-pixel look), a cut of a larger mask, and a mask of nothing.
TEST_GROUP(Blobs){};

TEST(Blobs, are_opencvs_connected_components) {
    cv::RNG rng(20261201);
    long blobs_seen = 0;
    for (int t = 0; t < 300; ++t) {
        // Drawn one at a time: the order a call's arguments are computed in is the compiler's, so
        // the same seed would give other masks on the Pi's build.
        const int rows = rng.uniform(1, 90);
        const int cols = rng.uniform(1, 150);
        cv::Mat mask(rows, cols, CV_8UC1);
        cv::Mat noise(mask.size(), CV_8UC1);
        rng.fill(noise, cv::RNG::UNIFORM, 0, 100);
        const int fill = rng.uniform(1, 80);
        mask = noise < fill;
        if (t % 3 == 0) {  // diagonal chains: neighbours only through a corner
            mask.setTo(0);
            for (int k = 0; k < 6; ++k) {
                int x = rng.uniform(0, mask.cols), y = rng.uniform(0, mask.rows);
                const int dx = rng.uniform(0, 2) * 2 - 1;
                for (; x >= 0 && x < mask.cols && y < mask.rows; x += dx, ++y)
                    mask.at<std::uint8_t>(y, x) = 255;
            }
        }
        cv::Mat labels, stats, centroids;
        const int count =
            cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
        std::vector<std::tuple<int, int, long, double, double>> expected;  // first pixel, stats
        for (int k = 1; k < count; ++k) {
            cv::Point first(-1, -1);
            for (int y = 0; y < mask.rows && first.y < 0; ++y)
                for (int x = 0; x < mask.cols; ++x)
                    if (labels.at<int>(y, x) == k) {
                        first = {x, y};
                        break;
                    }
            expected.emplace_back(first.y, first.x, stats.at<int>(k, cv::CC_STAT_AREA),
                                  centroids.at<double>(k, 0), centroids.at<double>(k, 1));
        }
        std::sort(expected.begin(), expected.end());
        const auto got = vision::blobs_of(mask);
        CHECK_EQUAL(expected.size(), got.size());
        for (std::size_t i = 0; i < got.size() && i < expected.size(); ++i) {
            CHECK_EQUAL(std::get<2>(expected[i]), got[i].area_px);
            CHECK_EQUAL(std::get<3>(expected[i]), got[i].centre_x_px);
            CHECK_EQUAL(std::get<4>(expected[i]), got[i].centre_y_px);
        }
        blobs_seen += static_cast<long>(got.size());
    }
    CHECK(blobs_seen > 3000);
    cv::Mat large(200, 300, CV_8UC1, cv::Scalar(0));
    cv::circle(large, {150, 100}, 40, cv::Scalar(255), 3);   // a ring: one blob
    cv::circle(large, {150, 100}, 10, cv::Scalar(255), -1);  // and a disc inside it
    const auto rings = vision::blobs_of(large(cv::Rect(60, 20, 200, 170)));
    CHECK_EQUAL(2U, rings.size());
    DOUBLES_EQUAL(90.0, rings[0].centre_x_px, 0.01);  // (150, 100) in the cut
    DOUBLES_EQUAL(80.0, rings[1].centre_y_px, 0.01);
    CHECK(vision::blobs_of(cv::Mat(5, 7, CV_8UC1, cv::Scalar(0))).empty());
    CHECK_THROWS(std::invalid_argument, vision::blobs_of(cv::Mat(8, 8, CV_16UC1)));
}

// The marks' mask is OpenCV's adaptiveThreshold (mean), bit for bit: random smooth images of
// many shapes, blocks from 3 to wider than the image, contrasts whole and fractional, negative,
// zero and past the grey scale, both polarities; into a buffer given (kept), none, one of another
// size, and the image's own (not written over). Even blocks and colour refused.
TEST_GROUP(LocalThreshold){};

TEST(LocalThreshold, is_opencvs_adaptive_threshold) {
    cv::RNG rng(20261202);
    const std::array<double, 11> contrasts{0, 1, 2, 7, 10.5, -3, -7.25, 0.5, -0.5, 254, 300};
    long marked = 0, checked = 0;
    for (int t = 0; t < 400; ++t) {
        const int rows = rng.uniform(1, 120);
        const int cols = rng.uniform(1, 200);
        cv::Mat image(rows, cols, CV_8UC1);
        rng.fill(image, cv::RNG::UNIFORM, 0, 256);
        const int blur = 2 * rng.uniform(0, 4) + 1;
        cv::GaussianBlur(image, image, cv::Size(blur, blur), 0);
        const int block = 2 * rng.uniform(1, 60) + 1;
        const bool dark = rng.uniform(0, 2) == 1;
        const double contrast = contrasts[static_cast<std::size_t>(rng.uniform(0, 11))];
        cv::Mat expected;
        cv::adaptiveThreshold(image, expected, 255, cv::ADAPTIVE_THRESH_MEAN_C,
                              dark ? cv::THRESH_BINARY_INV : cv::THRESH_BINARY, block,
                              dark ? contrast : -contrast);
        cv::Mat out;
        const int given = t % 4;  // none, the same size (kept), another size, the image itself
        if (given == 1) out.create(image.size(), CV_8UC1);
        if (given == 2) out.create(rows + 1, cols, CV_8UC1);
        const cv::Mat before = image.clone();
        const std::uint8_t* kept = out.data;
        if (given == 3) out = image;
        vision::local_threshold(image, block, dark, contrast, out);
        CHECK_EQUAL(0, cv::norm(expected, out, cv::NORM_INF));
        CHECK(expected.size() == out.size());
        if (given == 1) CHECK(out.data == kept);
        CHECK_EQUAL(0, cv::norm(before, image, cv::NORM_INF));
        marked += cv::countNonZero(expected);
        checked += static_cast<long>(expected.total());
    }
    // Neither all marks nor none: the rule is exercised both ways.
    CHECK(marked > checked / 10);
    CHECK(marked < checked * 9 / 10);
    cv::Mat out;
    CHECK_THROWS(std::invalid_argument,
                 vision::local_threshold(cv::Mat(8, 8, CV_8UC1), 4, true, 5, out));
    CHECK_THROWS(std::invalid_argument,
                 vision::local_threshold(cv::Mat(8, 8, CV_8UC3), 5, true, 5, out));
}

// The median is the value a full sort puts at the middle (the upper one for an even count), on
// both of its paths: few values, and many counted into buckets first. Sets of every size around
// the bucketed path's start, spread wide, clustered in ties a ring's levels make, with outliers
// far off, all equal, and with infinities and NaN (which go nth_element's way; NaN's rank is
// unspecified there, so only that a value comes back is checked).
TEST_GROUP(Median){};

TEST(Median, is_the_sorted_middle_on_both_paths) {
    cv::RNG rng(20261202);
    int checked = 0;
    for (int t = 0; t < 3000; ++t) {
        const int n = t < 600 ? 1 + t : rng.uniform(1, 2000);
        std::vector<double> values(static_cast<std::size_t>(n));
        const int kind = t % 4;
        for (double& v : values) {
            if (kind == 0)
                v = rng.uniform(-1e6, 1e6);
            else if (kind == 1)  // a ring's levels: grey counts less a smooth plane, many ties
                v = std::round(rng.gaussian(3) + 200) - 0.125 * rng.uniform(0, 8);
            else if (kind == 2)  // a tight cluster and a few far away
                v = rng.uniform(0, 50) == 0 ? rng.uniform(-1e9, 1e9) : 7 + rng.gaussian(1e-9);
            else
                v = rng.uniform(0, 3);
        }
        std::vector<double> sorted = values;
        std::sort(sorted.begin(), sorted.end());
        const double expected = sorted[sorted.size() / 2];
        if (median_of(values) != expected) {
            std::printf("median of %d values (kind %d): %.17g, sorted middle %.17g\n", n, kind,
                        median_of(values), expected);
            FAIL("median differs from the sorted middle");
        }
        ++checked;
    }
    CHECK_EQUAL(3000, checked);
    CHECK_EQUAL(4.5, median_of(std::vector<double>(300, 4.5)));
    std::vector<double> with_infinity(300, 1.0);
    with_infinity[7] = std::numeric_limits<double>::infinity();
    with_infinity[8] = -std::numeric_limits<double>::infinity();
    CHECK_EQUAL(1.0, median_of(with_infinity));
    with_infinity[9] = std::numeric_limits<double>::quiet_NaN();
    (void)median_of(with_infinity);
    CHECK_THROWS(std::invalid_argument, median_of({}));
}

// The patches' median is OpenCV's median, bit for bit: random images of every small shape (one
// pixel to wider than a run of the network), a patch cut from a larger image (its edge
// replicated, not read past), and the whole-photo path; other kernel sizes and colour refused.
TEST_GROUP(MedianFilter){};

TEST(MedianFilter, is_opencvs_median_bit_for_bit) {
    cv::RNG rng(20261129);
    long differing = 0, pixels = 0;
    for (const int kernel : {1, 3, 5})
        for (int t = 0; t < 200; ++t) {
            const int rows = rng.uniform(1, 140);  // one at a time, as for the blobs' masks
            const int cols = rng.uniform(1, 140);
            cv::Mat image(rows, cols, CV_8UC1);
            // Half the images noise over the whole range, half a few levels around a step (ties).
            if (t % 2 == 0)
                rng.fill(image, cv::RNG::UNIFORM, 0, 256);
            else
                for (int y = 0; y < image.rows; ++y)
                    for (int x = 0; x < image.cols; ++x)
                        image.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(
                            (x > image.cols / 2 ? 180 : 40) + rng.uniform(0, 4));
            cv::Mat expected;
            cv::medianBlur(image, expected, kernel);
            differing += cv::countNonZero(vision::median_filtered(image, kernel) != expected);
            pixels += static_cast<long>(image.total());
        }
    CHECK_EQUAL(0, differing);
    CHECK(pixels > 1'000'000 / 2);
    cv::Mat large(300, 400, CV_8UC1);
    rng.fill(large, cv::RNG::UNIFORM, 0, 256);
    cv::Mat expected;
    const cv::Mat patch = large(cv::Rect(100, 50, 61, 57));
    cv::medianBlur(patch.clone(), expected, 5);
    CHECK_EQUAL(0, cv::countNonZero(vision::median_filtered(patch, 5) != expected));
    cv::medianBlur(large, expected, 5);
    CHECK_EQUAL(0, cv::countNonZero(vision::median_filtered(large, 5) != expected));
    CHECK_THROWS(std::invalid_argument, vision::median_filtered(large, 7));
    CHECK_THROWS(std::invalid_argument, vision::median_filtered(cv::Mat(8, 8, CV_8UC3), 3));
}
