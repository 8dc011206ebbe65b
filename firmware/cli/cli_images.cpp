#include "firmware/cli/cli_images.hpp"

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <vector>

#include "firmware/cli/cli_args.hpp"

namespace calbox::cli {

namespace {

// A JPEG cut short (a copy or a transfer that stopped) still decodes: libjpeg fills the rest
// grey, says so on standard error, and the photo would be measured. Its last scan then has no
// end-of-image marker after it (entropy-coded data never holds a marker but a restart, so the
// last start-of-scan is the main image's, and an EXIF thumbnail's end marker lies before it).
bool truncated_jpeg(const std::vector<unsigned char>& bytes) {
    if (bytes.size() < 4 || bytes[0] != 0xFF || bytes[1] != 0xD8) return false;
    std::size_t last_scan = 0;
    for (std::size_t i = 0; i + 1 < bytes.size(); ++i)
        if (bytes[i] == 0xFF && bytes[i + 1] == 0xDA) last_scan = i;
    for (std::size_t i = last_scan; i + 1 < bytes.size(); ++i)
        if (bytes[i] == 0xFF && bytes[i + 1] == 0xD9) return false;
    return true;
}

}  // namespace

cv::Mat load_gray_image(const std::string& path) {
    if (!std::filesystem::is_regular_file(path))
        throw std::runtime_error("cannot read image " + path + ": no such file");
    const std::string text = read_input_file(path, "image");
    const std::vector<unsigned char> bytes(text.begin(), text.end());
    if (truncated_jpeg(bytes))
        throw std::runtime_error("cannot read image " + path +
                                 ": the JPEG is cut short (no end after its last scan)");
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
