#pragma once
// PNG and JPEG in memory, through libpng and libjpeg-turbo themselves, read and written as
// OpenCV's imgcodecs reads and writes them (tests/unit/test_image_codec.cpp holds the two to the
// same pixels and bytes). Not OpenCV's module because that module loads some 140 libraries (GDAL,
// GDCM, HEIF, ...) and GDCM's dictionary on every start of the box's binary: a fifth of a
// second per command here, most of a second on a Raspberry Pi.
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/image_view.hpp"

namespace calbox::vision {

// Bytes that are not an image these readers take, or pixels no file can hold; one line saying
// which.
struct ImageCodecError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// 8-bit pixels, `channels` of them a pixel: 1 (gray) or 3 (blue, green, red, as OpenCV holds
// colour), rows `stride_bytes` apart.
struct PixelRows {
    const std::uint8_t* pixels = nullptr;
    int width_px = 0, height_px = 0, stride_bytes = 0, channels = 1;
};

struct GrayPixels {
    int width_px = 0, height_px = 0;
    std::vector<std::uint8_t> pixels;  // rows packed, width_px apart

    GrayView view() const { return {pixels.data(), width_px, height_px, width_px}; }
};

// Filtered "sub" and zlib's fastest level with run-length matching, as OpenCV writes PNG.
std::vector<std::uint8_t> png_bytes(const PixelRows& image);
// Baseline JPEG at `quality` (1..100), as OpenCV writes it.
std::vector<std::uint8_t> jpeg_bytes(const PixelRows& image, int quality);

// A PNG or JPEG file's picture as 8-bit gray, as OpenCV's imdecode(IMREAD_GRAYSCALE) gives it:
// colour as luma, 16 bits to 8, transparency dropped, turned upright by the file's EXIF
// orientation. Throws ImageCodecError for anything else, a file the decoder stops on, or what
// image_bytes_problem finds (an empty file, a JPEG cut short).
GrayPixels decode_gray(std::span<const std::uint8_t> bytes);

}  // namespace calbox::vision
