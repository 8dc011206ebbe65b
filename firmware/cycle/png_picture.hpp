#pragma once
// PNG bytes of an OpenCV picture (gray or BGR). Include only from .cpp files: it brings in
// OpenCV's core; firmware/cycle/png.hpp is the plain interface for the box's frames and bitmaps.
#include <opencv2/core.hpp>
#include <string>

#include "core/vision/image_view.hpp"

namespace calbox::firmware {

std::string png_of_picture(const cv::Mat& picture);  // throws std::runtime_error
// A gray photo as a BGR picture to draw on in colour.
cv::Mat colour_picture_of(const vision::GrayView& photo);

}  // namespace calbox::firmware
