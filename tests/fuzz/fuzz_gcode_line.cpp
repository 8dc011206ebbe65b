// Fuzz target: the G-code line reader (what the twin and the machine link parse).
#include "core/gcode/gcode_line.hpp"
#include "tests/fuzz/fuzz_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        calbox::gcode::parse_line(calbox::fuzz::as_text(data, size));
    } catch (const calbox::gcode::SyntaxError&) {
    }
    return 0;
}
