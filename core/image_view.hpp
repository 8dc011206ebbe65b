#pragma once
// A borrowed 8-bit grey image; the caller keeps the pixels alive.
#include <cstdint>
#include <stdexcept>

namespace calbox::vision {

struct GrayView {
    const std::uint8_t* pixels = nullptr;
    int width_px = 0;
    int height_px = 0;
    int stride_bytes = 0;

    std::uint8_t at(int x, int y) const { return pixels[static_cast<long>(y) * stride_bytes + x]; }
    void check() const {
        if (pixels == nullptr || width_px <= 0 || height_px <= 0 || stride_bytes < width_px) {
            throw std::invalid_argument("empty or malformed image");
        }
    }
};

}  // namespace calbox::vision
