#include "core/vision/image_bytes.hpp"

namespace calbox::vision {
namespace {

// A JPEG's last scan with no end-of-image marker after it. Entropy-coded data never holds a
// marker but a restart, so the last start-of-scan is the main image's, and an EXIF thumbnail's
// end marker lies before it.
bool truncated_jpeg(std::span<const std::uint8_t> bytes) {
    if (bytes.size() < 4 || bytes[0] != 0xFF || bytes[1] != 0xD8) return false;
    std::size_t last_scan = 0;
    for (std::size_t i = 0; i + 1 < bytes.size(); ++i)
        if (bytes[i] == 0xFF && bytes[i + 1] == 0xDA) last_scan = i;
    for (std::size_t i = last_scan; i + 1 < bytes.size(); ++i)
        if (bytes[i] == 0xFF && bytes[i + 1] == 0xD9) return false;
    return true;
}

}  // namespace

std::string image_bytes_problem(std::span<const std::uint8_t> bytes) {
    if (bytes.empty()) return "the file is empty";
    if (truncated_jpeg(bytes)) return "the JPEG is cut short (no end after its last scan)";
    return {};
}

}  // namespace calbox::vision
