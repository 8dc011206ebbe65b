#include "firmware/cycle/png.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "firmware/cycle/png_picture.hpp"

namespace calbox::firmware {
std::string png_of_picture(const cv::Mat& picture) {
    std::vector<std::uint8_t> bytes;
    if (!cv::imencode(".png", picture, bytes)) throw std::runtime_error("PNG encoding failed");
    return {bytes.begin(), bytes.end()};
}

std::string overlay_png_of(const cv::Mat& picture) {
    if (picture.cols <= kOverlayWidthPx) return png_of_picture(picture);
    // A whole factor, so that the drawn lines stay as sharp as they were drawn.
    const int factor = (picture.cols + kOverlayWidthPx - 1) / kOverlayWidthPx;
    cv::Mat smaller;
    cv::resize(picture, smaller, {picture.cols / factor, picture.rows / factor}, 0, 0,
               cv::INTER_AREA);
    return png_of_picture(smaller);
}

cv::Mat colour_picture_of(const vision::GrayView& photo) {
    const cv::Mat gray(photo.height_px, photo.width_px, CV_8UC1,
                       const_cast<std::uint8_t*>(photo.pixels),
                       static_cast<std::size_t>(photo.stride_bytes));
    cv::Mat picture;
    cv::cvtColor(gray, picture, cv::COLOR_GRAY2BGR);
    return picture;
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
