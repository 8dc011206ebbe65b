#pragma once
// PNG bytes of an OpenCV picture (gray or BGR). Include only from .cpp files: it brings in
// OpenCV's core; firmware/cycle/png.hpp is the plain interface for the box's frames and bitmaps.
#include <opencv2/core.hpp>
#include <string>

#include "core/image_view.hpp"

namespace calbox::firmware {

std::string png_of_picture(const cv::Mat& picture);  // throws std::runtime_error
// An overlay drawn on a photo, as a person looks at it: at most kOverlayWidthPx wide (a 12 MP
// photo's halved), the measurement being in the records' figures. PNG's filtering and checksums
// of a full 12 MP colour picture cost the box 0.6 s a cycle's photo; halved, 0.15 s.
constexpr int kOverlayWidthPx = 2048;
// The photo reduced by a whole factor to at most kOverlayWidthPx wide, in colour, to draw on: the
// gray photo is reduced before it is coloured and drawn on, not the colour picture after (a 12 MP
// photo's colour copy and its reduction cost the box 0.13 s a photo). Drawings are given in the
// photo's pixels and sizes and land where they would on the photo itself.
struct OverlayCanvas {
    cv::Mat picture;  // BGR, the photo's size over `factor`
    int factor = 1;
    cv::Point at(double x_px, double y_px) const;
    // A line width or a radius of `photo_px` on the photo, at least a pixel.
    int size(double photo_px) const;
    double font_scale(double on_photo) const { return on_photo / factor; }
};
OverlayCanvas overlay_canvas_of(const vision::GrayView& photo);
std::string png_of(const OverlayCanvas& canvas);

}  // namespace calbox::firmware
