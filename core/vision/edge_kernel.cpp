#include "core/vision/edge_kernel.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace calbox::vision {

bool sample_profile_q8(const GrayView& image, std::int64_t x0_q16, std::int64_t y0_q16,
                       std::int64_t dx_q16, std::int64_t dy_q16, int count, std::int32_t* out) {
    const std::int64_t max_x = static_cast<std::int64_t>(image.width_px - 1) * kQ16;
    const std::int64_t max_y = static_cast<std::int64_t>(image.height_px - 1) * kQ16;
    std::int64_t x = x0_q16, y = y0_q16;
    for (int i = 0; i < count; ++i, x += dx_q16, y += dy_q16) {
        if (x < 0 || y < 0 || x >= max_x || y >= max_y) return false;
        const int ix = static_cast<int>(x >> 16), iy = static_cast<int>(y >> 16);
        // Weights in 1/65536 of a pixel; the row sums stay below 2^24, the total below 2^40.
        const std::int64_t fx = x & 0xffff, fy = y & 0xffff;
        const std::uint8_t* row0 = image.pixels + static_cast<long>(iy) * image.stride_bytes + ix;
        const std::uint8_t* row1 = row0 + image.stride_bytes;
        const std::int64_t top = row0[0] * (kQ16 - fx) + row0[1] * fx;
        const std::int64_t bottom = row1[0] * (kQ16 - fx) + row1[1] * fx;
        out[i] = static_cast<std::int32_t>(
            (top * (kQ16 - fy) + bottom * fy + (std::int64_t{1} << 23)) >> 24);
    }
    return true;
}

std::optional<std::int64_t> step_edge_q16(const std::int32_t* profile_q8, int count, bool rising,
                                          const EdgeKernelSettings& settings) {
    if (count < 3) return std::nullopt;
    const auto gradient = [&](int i) {
        return rising ? profile_q8[i + 1] - profile_q8[i] : profile_q8[i] - profile_q8[i + 1];
    };
    std::int32_t peak = 0;
    int at_peak = 0;
    for (int i = 0; i + 1 < count; ++i) {
        if (gradient(i) > peak) peak = gradient(i), at_peak = i;
    }
    if (peak <= 0) return std::nullopt;
    const std::int32_t floor = peak / std::max(1, settings.gradient_floor_divisor);
    // Only the steepest step's own lobe: a second step further along the profile (a glossy
    // strand's highlight, the next strand) is another edge, not part of this one.
    int first = at_peak, last = at_peak;
    while (first > 0 && gradient(first - 1) > floor) --first;
    while (last + 2 < count && gradient(last + 1) > floor) ++last;
    std::int64_t weight = 0, moment = 0;  // moment in half samples: gradient i sits at i + 1/2
    for (int i = first; i <= last; ++i) {
        const std::int64_t w = gradient(i) - floor;
        weight += w;
        moment += w * (2 * i + 1);
    }
    return (moment * (kQ16 / 2) + weight / 2) / weight;
}

std::optional<geometry::Point2> step_edge_on_segment(const GrayView& image, geometry::Point2 from,
                                                     geometry::Point2 to, bool rising,
                                                     const EdgeKernelSettings& settings) {
    const double step = settings.sample_step_px;
    if (!(step > 0)) throw std::invalid_argument("an edge profile's sample step must be positive");
    const double length = std::hypot(to.x - from.x, to.y - from.y);
    const int count = static_cast<int>(length / step) + 1;
    if (count < 3) return std::nullopt;
    const double ux = (to.x - from.x) / length, uy = (to.y - from.y) / length;
    std::vector<std::int32_t> profile(static_cast<std::size_t>(count));
    if (!sample_profile_q8(image, to_q16(from.x), to_q16(from.y), to_q16(ux * step),
                           to_q16(uy * step), count, profile.data())) {
        return std::nullopt;
    }
    const auto edge = step_edge_q16(profile.data(), count, rising, settings);
    if (!edge) return std::nullopt;
    const double along = from_q16(*edge) * step;
    return geometry::Point2{from.x + ux * along, from.y + uy * along};
}

double sample_reference(const GrayView& image, double x, double y) {
    const int ix = static_cast<int>(std::floor(x)), iy = static_cast<int>(std::floor(y));
    const double fx = x - ix, fy = y - iy;
    const auto at = [&](int u, int v) { return static_cast<double>(image.at(u, v)); };
    return (at(ix, iy) * (1 - fx) + at(ix + 1, iy) * fx) * (1 - fy) +
           (at(ix, iy + 1) * (1 - fx) + at(ix + 1, iy + 1) * fx) * fy;
}

std::optional<double> step_edge_reference(const std::vector<double>& profile, bool rising,
                                          const EdgeKernelSettings& settings) {
    if (profile.size() < 3) return std::nullopt;
    double peak = 0;
    std::size_t at_peak = 0;
    std::vector<double> g(profile.size() - 1);
    for (std::size_t i = 0; i + 1 < profile.size(); ++i) {
        g[i] = rising ? profile[i + 1] - profile[i] : profile[i] - profile[i + 1];
        if (g[i] > peak) peak = g[i], at_peak = i;
    }
    if (peak <= 0) return std::nullopt;
    const double floor = peak / std::max(1, settings.gradient_floor_divisor);
    std::size_t first = at_peak, last = at_peak;
    while (first > 0 && g[first - 1] > floor) --first;
    while (last + 1 < g.size() && g[last + 1] > floor) ++last;
    double weight = 0, moment = 0;
    for (std::size_t i = first; i <= last; ++i) {
        weight += g[i] - floor;
        moment += (g[i] - floor) * (static_cast<double>(i) + 0.5);
    }
    return moment / weight;
}

}  // namespace calbox::vision
