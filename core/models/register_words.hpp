#pragma once
// 32-bit floats in two 16-bit Modbus registers, in a stated word order. The register values are
// numbers (Modbus sends each big-endian on the wire); the order says where each byte of the
// IEEE 754 value goes: ABCD has the most significant byte first (123456.0f is 0x47F1 0x2000).
// Packed here rather than with libmodbus 3.1.6's helpers, whose "big-endian" is not.
#include <array>
#include <cstdint>
#include <string>

namespace calbox::models {

enum class WordOrder { abcd, cdab, badc, dcba };

WordOrder parse_word_order(const std::string& text);  // throws std::invalid_argument
const char* word_order_name(WordOrder order);
std::array<std::uint16_t, 2> pack_float(float value, WordOrder order);
float unpack_float(std::array<std::uint16_t, 2> words, WordOrder order);

}  // namespace calbox::models
