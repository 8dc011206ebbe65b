#include "firmware/cycle/png.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/vision/image_codec.hpp"
#include "firmware/cycle/png_picture.hpp"

namespace calbox::firmware {
std::string png_of_picture(const cv::Mat& picture) {
    const auto bytes = vision::png_bytes({picture.data, picture.cols, picture.rows,
                                          static_cast<int>(picture.step[0]), picture.channels()});
    return {bytes.begin(), bytes.end()};
}

cv::Point OverlayCanvas::at(double x_px, double y_px) const {
    return {cvRound((x_px + 0.5) / factor - 0.5), cvRound((y_px + 0.5) / factor - 0.5)};
}

int OverlayCanvas::size(double photo_px) const {
    return std::max(1, static_cast<int>(std::lround(photo_px / factor)));
}

OverlayCanvas overlay_canvas_of(const vision::GrayView& photo) {
    photo.check();
    const cv::Mat gray(photo.height_px, photo.width_px, CV_8UC1,
                       const_cast<std::uint8_t*>(photo.pixels),
                       static_cast<std::size_t>(photo.stride_bytes));
    OverlayCanvas canvas;
    // A whole factor, so that the drawn lines stay as sharp as they were drawn.
    canvas.factor = (photo.width_px + kOverlayWidthPx - 1) / kOverlayWidthPx;
    cv::Mat smaller;
    if (canvas.factor > 1)
        cv::resize(gray, smaller, {photo.width_px / canvas.factor, photo.height_px / canvas.factor},
                   0, 0, cv::INTER_AREA);
    else
        smaller = gray;
    cv::cvtColor(smaller, canvas.picture, cv::COLOR_GRAY2BGR);
    return canvas;
}

std::string png_of(const OverlayCanvas& canvas) {
    return png_of_picture(canvas.picture);
}

std::string png_of(const hal::Frame& frame) {
    const cv::Mat view(frame.height_px, frame.width_px, CV_8UC1,
                       const_cast<std::uint8_t*>(frame.pixels.data()),
                       static_cast<std::size_t>(frame.stride_bytes));
    return png_of_picture(view);
}

std::string png_of(const hal::MonoBitmap& bitmap) {
    cv::Mat image(bitmap.height_px(), bitmap.width_px(), CV_8UC1);
    for (int y = 0; y < bitmap.height_px(); ++y)
        for (int x = 0; x < bitmap.width_px(); ++x)
            image.at<std::uint8_t>(y, x) = bitmap.at(x, y) ? 255 : 0;
    return png_of_picture(image);
}

}  // namespace calbox::firmware
