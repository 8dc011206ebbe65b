#pragma once
// PNG files of the box's pictures, for its records (OpenCV's encoder behind a plain interface).
#include <string>

#include "hal/camera.hpp"
#include "hal/display.hpp"

namespace calbox::firmware {

std::string png_of(const hal::Frame& frame);        // 8-bit gray
std::string png_of(const hal::MonoBitmap& bitmap);  // 1-bit as black and white

}  // namespace calbox::firmware
