#pragma once
// Photos from image files as the camera: a cycle re-run on saved photos, or on photos taken
// with another camera. Each capture takes the next files in name order.
#include <filesystem>
#include <string>
#include <vector>

#include "hal/background_job.hpp"
#include "hal/camera.hpp"

namespace calbox::drivers {

class FileCamera final : public hal::Camera {
  public:
    // `source` is a directory (its .png, .jpg, .jpeg, .bmp, .tif, .tiff, .pgm files) or a glob
    // pattern. Throws std::runtime_error naming it when it matches no image file.
    explicit FileCamera(const std::string& source);
    void start_capture(const hal::CaptureRequest& request) override;
    int completion_fd() const override { return capture_.fd(); }
    // An unreadable file, photos run out, or a photo whose size differs from the first one's:
    // an error naming the file.
    hal::CaptureResult take_frames() override;
    const std::vector<std::filesystem::path>& files() const { return files_; }

  private:
    std::string source_;
    std::vector<std::filesystem::path> files_;
    std::size_t next_ = 0;
    int width_px_ = 0, height_px_ = 0;  // the first photo's
    hal::BackgroundJob<hal::CaptureResult> capture_;
};

// A grey frame as an 8-bit PNG (lossless, so a re-run sees the same pixels); throws
// std::runtime_error naming the file.
void write_frame_png(const std::filesystem::path& path, const hal::Frame& frame);

}  // namespace calbox::drivers
