#include "drivers/file_camera.hpp"

#include <glob.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <set>
#include <stdexcept>
#include <vector>

#include "core/vision/image_codec.hpp"

namespace calbox::drivers {
namespace {

bool is_image(const std::filesystem::path& p) {
    static const std::set<std::string> kinds{".png", ".jpg",  ".jpeg", ".bmp",
                                             ".tif", ".tiff", ".pgm"};
    std::string ext = p.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return kinds.count(ext) != 0;
}

std::vector<std::filesystem::path> images_of(const std::string& source) {
    std::vector<std::filesystem::path> files;
    std::error_code ec;
    if (std::filesystem::is_directory(source, ec)) {
        for (const auto& entry : std::filesystem::directory_iterator(source, ec)) {
            if (entry.is_regular_file() && is_image(entry.path())) files.push_back(entry.path());
        }
        if (ec) throw std::runtime_error(source + ": cannot list: " + ec.message());
    } else {
        glob_t found{};
        if (::glob(source.c_str(), 0, nullptr, &found) == 0) {
            for (std::size_t i = 0; i < found.gl_pathc; ++i) {
                const std::filesystem::path p = found.gl_pathv[i];
                if (is_image(p)) files.push_back(p);
            }
        }
        ::globfree(&found);
    }
    std::sort(files.begin(), files.end());
    if (files.empty()) {
        throw std::runtime_error(source + ": no photos (.png, .jpg, .bmp, .tif, .pgm) there");
    }
    return files;
}

}  // namespace

FileCamera::FileCamera(const std::string& source) : source_(source), files_(images_of(source)) {}

void FileCamera::start_capture(const hal::CaptureRequest& request) {
    if (capture_.busy()) throw std::logic_error("a capture is already running");
    const std::size_t count = static_cast<std::size_t>(std::max(1, request.frame_count));
    const std::size_t first = next_;
    next_ += count;
    capture_.start([this, first, count] {
        hal::CaptureResult result;
        for (std::size_t k = first; k < first + count; ++k) {
            if (k >= files_.size()) {
                result.frames.clear();
                result.error = "camera: " + source_ + ": no photo left (all " +
                               std::to_string(files_.size()) + " used)";
                break;
            }
            // OpenCV says only "empty" for a file it could not open: ask the system why.
            if (::access(files_[k].c_str(), R_OK) != 0) {
                result.frames.clear();
                result.error =
                    "camera: " + files_[k].string() + ": cannot read: " + std::strerror(errno);
                break;
            }
            std::ifstream in(files_[k], std::ios::binary);
            const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                                  std::istreambuf_iterator<char>());
            vision::GrayPixels gray;
            try {
                gray = vision::decode_gray(bytes);
            } catch (const vision::ImageCodecError& e) {
                result.frames.clear();
                result.error = "camera: " + files_[k].string() + ": " + e.what();
                break;
            }
            if (width_px_ == 0) {
                width_px_ = gray.width_px;
                height_px_ = gray.height_px;
            }
            if (gray.width_px != width_px_ || gray.height_px != height_px_) {
                result.frames.clear();
                result.error = "camera: " + files_[k].string() + " is " +
                               std::to_string(gray.width_px) + "x" +
                               std::to_string(gray.height_px) + ", the photos before it " +
                               std::to_string(width_px_) + "x" + std::to_string(height_px_);
                break;
            }
            hal::Frame frame;
            frame.width_px = gray.width_px;
            frame.height_px = gray.height_px;
            frame.stride_bytes = gray.width_px;
            frame.format = hal::PixelFormat::gray8;
            frame.pixels = std::move(gray.pixels);
            frame.metadata.sequence = k;
            result.frames.push_back(std::move(frame));
        }
        return result;
    });
}

hal::CaptureResult FileCamera::take_frames() {
    auto result = capture_.take();
    if (!result) return hal::CaptureResult{{}, "camera: no capture has finished"};
    return std::move(*result);
}

void write_frame_png(const std::filesystem::path& path, const hal::Frame& frame) {
    if (frame.format != hal::PixelFormat::gray8) {
        throw std::runtime_error(path.string() + ": only grey frames are saved");
    }
    const auto png = vision::png_bytes(
        {frame.pixels.data(), frame.width_px, frame.height_px, frame.stride_bytes, 1});
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
    out.close();
    if (!out) throw std::runtime_error(path.string() + ": cannot write the photo");
}

}  // namespace calbox::drivers
