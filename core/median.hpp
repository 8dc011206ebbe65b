#pragma once
// The middle of a set of numbers: robust where a mean is pulled by a neighbour's edge or a speck.
#include <algorithm>
#include <stdexcept>
#include <vector>

namespace calbox {

// The upper middle for an even count (one of the values, not an average of two). Throws
// std::invalid_argument for no values.
inline double median_of(std::vector<double> values) {
    if (values.empty()) throw std::invalid_argument("the median of no values");
    const auto middle = values.begin() + static_cast<long>(values.size() / 2);
    std::nth_element(values.begin(), middle, values.end());
    return *middle;
}

}  // namespace calbox
