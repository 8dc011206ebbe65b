#include "firmware/cli/cli_images.hpp"

#include <filesystem>
#include <stdexcept>
#include <vector>

#include "core/vision/image_codec.hpp"
#include "firmware/cli/cli_args.hpp"

namespace calbox::cli {

cv::Mat load_gray_image(const std::string& path) {
    if (!std::filesystem::is_regular_file(path))
        throw std::runtime_error("cannot read image " + path + ": no such file");
    const std::string text = read_input_file(path, "image");
    const std::vector<unsigned char> bytes(text.begin(), text.end());
    try {
        const auto gray = vision::decode_gray(bytes);
        return cv::Mat(gray.height_px, gray.width_px, CV_8UC1,
                       const_cast<std::uint8_t*>(gray.pixels.data()))
            .clone();
    } catch (const vision::ImageCodecError& e) {
        throw std::runtime_error("cannot read image " + path + ": " + e.what());
    }
}

vision::GrayView view_of(const cv::Mat& gray) {
    return {gray.data, gray.cols, gray.rows, static_cast<int>(gray.step[0])};
}

void write_png(const std::string& path, const cv::Mat& image) {
    if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3))
        throw std::runtime_error("cannot encode " + path + " as PNG: not 8-bit gray or colour");
    const auto png = vision::png_bytes(
        {image.data, image.cols, image.rows, static_cast<int>(image.step[0]), image.channels()});
    write_output_file(path, std::string(png.begin(), png.end()));
}

}  // namespace calbox::cli
