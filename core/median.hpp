#pragma once
// The middle of a set of numbers: robust where a mean is pulled by a neighbour's edge or a speck.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <vector>

namespace calbox {

// The upper middle for an even count (one of the values, not an average of two). Throws
// std::invalid_argument for no values.
//
// Many values are first counted into buckets between their least and greatest, and only the
// bucket holding the middle is selected in: a mark's ring of some 700 levels took a frame's
// twelfth through std::nth_element alone, a selection branching on every comparison. A bucket's
// index grows with the value (a difference and a product rounded, then floored, never decrease),
// so the value found is the one nth_element finds. Values that are not all finite take
// nth_element's path.
inline double median_of(std::vector<double> values) {
    if (values.empty()) throw std::invalid_argument("the median of no values");
    const std::size_t middle_rank = values.size() / 2;
    constexpr std::size_t kBucketedFrom = 128, kBuckets = 256;
    if (values.size() >= kBucketedFrom) {
        const auto [least, greatest] = std::minmax_element(values.begin(), values.end());
        const double low = *least, span = *greatest - *least;
        bool finite = std::isfinite(span);
        for (double v : values) finite = finite && std::isfinite(v);
        if (finite) {
            if (span == 0) return low;
            const double per_value = static_cast<double>(kBuckets - 1) / span;
            const auto bucket_of = [&](double v) {
                return std::min(kBuckets - 1, static_cast<std::size_t>((v - low) * per_value));
            };
            std::array<std::size_t, kBuckets> count{};
            for (double v : values) ++count[bucket_of(v)];
            std::size_t bucket = 0, below = 0;
            while (below + count[bucket] <= middle_rank) below += count[bucket++];
            std::size_t kept = 0;
            for (double v : values)
                if (bucket_of(v) == bucket) values[kept++] = v;
            const auto middle = values.begin() + static_cast<long>(middle_rank - below);
            std::nth_element(values.begin(), middle, values.begin() + static_cast<long>(kept));
            return *middle;
        }
    }
    const auto middle = values.begin() + static_cast<long>(middle_rank);
    std::nth_element(values.begin(), middle, values.end());
    return *middle;
}

}  // namespace calbox
