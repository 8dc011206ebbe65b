#pragma once
// One number as text by a printf format ("%.3f"), for messages and machine files: core's one
// way to print a number, without streams and their locale.
#include <charconv>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace calbox {

inline std::string number_text(const char* format, double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, format, value);
    return buffer;
}

// number_text("%.<decimals>f", value), character for character (std::to_chars's fixed form is
// printf's), without printf's format parsing and its arbitrary-precision digits: a job's
// coordinates, tens of thousands of lines a cycle.
inline std::string fixed_text(double value, int decimals) {
    char buffer[400];  // the largest double's digits and a few hundred decimals
    const auto [end, error] =
        std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::fixed, decimals);
    if (error != std::errc{})
        throw std::invalid_argument("fixed_text: " + std::to_string(decimals) + " decimals");
    return {buffer, end};
}

}  // namespace calbox
