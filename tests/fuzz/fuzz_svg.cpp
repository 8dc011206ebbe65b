// Fuzz target: the SVG reader (calbox target svg).
#include "core/drawings/svg.hpp"
#include "tests/fuzz/fuzz_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        calbox::drawings::parse_svg(calbox::fuzz::as_text(data, size));
    } catch (const calbox::drawings::SvgError&) {
    }
    return 0;
}
