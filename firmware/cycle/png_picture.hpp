#pragma once
// PNG bytes of an OpenCV picture (gray or BGR). Include only from .cpp files: it brings in
// OpenCV's core; firmware/cycle/png.hpp is the plain interface for the box's frames and bitmaps.
#include <opencv2/core.hpp>
#include <string>

#include "core/vision/image_view.hpp"

namespace calbox::firmware {

std::string png_of_picture(const cv::Mat& picture);  // throws std::runtime_error
// An overlay drawn on a photo, as a person looks at it: at most kOverlayWidthPx wide (a 12 MP
// photo's halved), the measurement being in the records' figures. PNG's filtering and checksums
// of a full 12 MP colour picture cost the box 0.6 s a cycle's photo; halved, 0.15 s.
constexpr int kOverlayWidthPx = 2048;
std::string overlay_png_of(const cv::Mat& picture);
// A gray photo as a BGR picture to draw on in colour.
cv::Mat colour_picture_of(const vision::GrayView& photo);

}  // namespace calbox::firmware
