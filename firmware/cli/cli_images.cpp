#include "firmware/cli/cli_images.hpp"

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <vector>

#include "core/vision/image_bytes.hpp"
#include "firmware/cli/cli_args.hpp"

namespace calbox::cli {

cv::Mat load_gray_image(const std::string& path) {
    if (!std::filesystem::is_regular_file(path))
        throw std::runtime_error("cannot read image " + path + ": no such file");
    const std::string text = read_input_file(path, "image");
    const std::vector<unsigned char> bytes(text.begin(), text.end());
    if (const auto problem = vision::image_bytes_problem(bytes); !problem.empty())
        throw std::runtime_error("cannot read image " + path + ": " + problem);
    cv::Mat image = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
    if (image.empty())
        throw std::runtime_error("cannot read image " + path + ": not an image OpenCV can decode");
    if (image.depth() != CV_8U) image.convertTo(image, CV_8U);
    return image;
}

vision::GrayView view_of(const cv::Mat& gray) {
    return {gray.data, gray.cols, gray.rows, static_cast<int>(gray.step[0])};
}

void write_png(const std::string& path, const cv::Mat& image) {
    std::vector<unsigned char> png;
    if (!cv::imencode(".png", image, png))
        throw std::runtime_error("cannot encode " + path + " as PNG");
    write_output_file(path, std::string(png.begin(), png.end()));
}

}  // namespace calbox::cli
