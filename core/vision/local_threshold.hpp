#pragma once
// The pixels darker (or lighter) than the mean of their square neighbourhood by a contrast:
// cv::adaptiveThreshold's ADAPTIVE_THRESH_MEAN_C mask (255 or 0), bit for bit, into a buffer the
// caller may give. OpenCV's threshold step looks every pixel up in a table one at a time (4 ms of a
// halved 12 MP frame, against under a millisecond for a comparison of whole rows), and a fresh
// 3 MB mask is a page fault for every 4 KiB of it: the halved photo, no longer read once it is
// median-filtered, holds the mean and then the mask.
#include <opencv2/core/mat.hpp>

namespace calbox::vision {

// `dark`: marks below the mean by `contrast_dn` (THRESH_BINARY_INV with delta contrast_dn), else
// above it (THRESH_BINARY with delta -contrast_dn). `block_px` odd, at least 3. `out` keeps its
// buffer when it has the image's size and type and is not the image itself. Throws
// std::invalid_argument for an image that is not 8-bit single-channel or a block that is not odd.
void local_threshold(const cv::Mat& image, int block_px, bool dark, double contrast_dn,
                     cv::Mat& out);

}  // namespace calbox::vision
