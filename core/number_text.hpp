#pragma once
// One number as text by a printf format ("%.3f"), for messages and machine files: core's one
// way to print a number, without streams and their locale.
#include <cstdio>
#include <string>

namespace calbox {

inline std::string number_text(const char* format, double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, format, value);
    return buffer;
}

}  // namespace calbox
