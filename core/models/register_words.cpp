#include "core/models/register_words.hpp"

#include <bit>
#include <stdexcept>

namespace calbox::models {
namespace {

std::uint16_t swap_bytes(std::uint16_t w) {
    return static_cast<std::uint16_t>((w << 8) | (w >> 8));
}

}  // namespace

WordOrder parse_word_order(const std::string& text) {
    if (text == "abcd") return WordOrder::abcd;
    if (text == "cdab") return WordOrder::cdab;
    if (text == "badc") return WordOrder::badc;
    if (text == "dcba") return WordOrder::dcba;
    throw std::invalid_argument("word order '" + text + "' is not abcd, cdab, badc or dcba");
}

const char* word_order_name(WordOrder order) {
    switch (order) {
        case WordOrder::abcd:
            return "abcd";
        case WordOrder::cdab:
            return "cdab";
        case WordOrder::badc:
            return "badc";
        case WordOrder::dcba:
            return "dcba";
    }
    return "?";
}

std::array<std::uint16_t, 2> pack_float(float value, WordOrder order) {
    const auto bits = std::bit_cast<std::uint32_t>(value);
    const auto high = static_cast<std::uint16_t>(bits >> 16);     // bytes A B
    const auto low = static_cast<std::uint16_t>(bits & 0xFFFFU);  // bytes C D
    switch (order) {
        case WordOrder::abcd:
            return {high, low};
        case WordOrder::cdab:
            return {low, high};
        case WordOrder::badc:
            return {swap_bytes(high), swap_bytes(low)};
        case WordOrder::dcba:
            return {swap_bytes(low), swap_bytes(high)};
    }
    return {high, low};
}

float unpack_float(std::array<std::uint16_t, 2> w, WordOrder order) {
    std::uint16_t high = w[0], low = w[1];
    switch (order) {
        case WordOrder::abcd:
            break;
        case WordOrder::cdab:
            high = w[1];
            low = w[0];
            break;
        case WordOrder::badc:
            high = swap_bytes(w[0]);
            low = swap_bytes(w[1]);
            break;
        case WordOrder::dcba:
            high = swap_bytes(w[1]);
            low = swap_bytes(w[0]);
            break;
    }
    return std::bit_cast<float>(static_cast<std::uint32_t>(high) << 16 | low);
}

}  // namespace calbox::models
