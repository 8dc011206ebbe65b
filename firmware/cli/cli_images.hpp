#pragma once
// Image files for the command line (OpenCV stays out of widely included headers).
#include <opencv2/core.hpp>
#include <string>

#include "core/image_view.hpp"

namespace calbox::cli {

// An 8-bit grey image; throws std::runtime_error naming the file when it is missing or is not
// an image OpenCV can read.
cv::Mat load_gray_image(const std::string& path);
vision::GrayView view_of(const cv::Mat& gray);
void write_png(const std::string& path, const cv::Mat& image);

}  // namespace calbox::cli
