#pragma once
// An image file's bytes checked before they are decoded. OpenCV decodes some broken files
// without a word of its own: a JPEG cut short (a copy or a transfer that stopped) comes back
// whole, the missing part filled grey, with only libjpeg's note on standard error, and would be
// measured; an empty file stops on an assertion in OpenCV's own words. Both are said here, once,
// for every reader of photos (the command line, the file camera).
#include <cstdint>
#include <span>
#include <string>

namespace calbox::vision {

// Why these bytes are not a photo to measure, or empty when nothing is seen wrong (the decoder
// may still refuse them).
std::string image_bytes_problem(std::span<const std::uint8_t> bytes);

}  // namespace calbox::vision
