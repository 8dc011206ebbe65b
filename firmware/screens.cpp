#include "firmware/screens.hpp"

#include <opencv2/imgproc.hpp>

namespace calbox::firmware {

// OpenCV's Hershey simplex font at a scale where a line is 11 px: five lines on 64.
hal::MonoBitmap text_screen(const std::string& title, const std::vector<std::string>& lines) {
    cv::Mat canvas(64, 128, CV_8UC1, cv::Scalar(0));
    cv::rectangle(canvas, {0, 0}, {127, 11}, cv::Scalar(255), cv::FILLED);
    cv::putText(canvas, title, {2, 9}, cv::FONT_HERSHEY_PLAIN, 0.75, cv::Scalar(0), 1, cv::LINE_8);
    int y = 24;
    for (const auto& line : lines) {
        if (y > 63) break;
        cv::putText(canvas, line, {2, y}, cv::FONT_HERSHEY_PLAIN, 0.75, cv::Scalar(255), 1,
                    cv::LINE_8);
        y += 13;
    }
    hal::MonoBitmap bitmap(128, 64);
    for (int r = 0; r < 64; ++r)
        for (int c = 0; c < 128; ++c) bitmap.set(c, r, canvas.at<std::uint8_t>(r, c) > 127);
    return bitmap;
}

}  // namespace calbox::firmware
