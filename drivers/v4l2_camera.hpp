#pragma once
// A V4L2 camera (USB cameras, and the fallback when libcamera finds none): mmap streaming of
// GREY, YUYV (its Y plane taken as grey) or MJPEG (decoded by OpenCV), the size asked for,
// manual exposure and gain where the device has them. A capture runs on a thread of its own
// and signals its end on an eventfd.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hal/background_job.hpp"
#include "hal/camera.hpp"

namespace calbox::drivers {

// The seam over the kernel: one opened video node. The real one calls ioctl(2) and mmap(2);
// tests give a device that speaks the same protocol from memory, and can fail as a real one
// does (EAGAIN, ENODEV when it is unplugged).
class V4l2Device {
  public:
    virtual ~V4l2Device() = default;
    virtual const std::string& path() const = 0;
    // As ioctl(2): 0, or -1 with errno set.
    virtual int ioctl(unsigned long request, void* argument) = 0;
    // As mmap(2) of `length` bytes at `offset` for reading; nullptr with errno set on failure.
    virtual void* map(std::size_t length, std::int64_t offset) = 0;
    virtual void unmap(void* address, std::size_t length) = 0;
    // Readable when a filled buffer can be dequeued.
    virtual int poll_fd() const = 0;
};

// Opens the node. Throws std::runtime_error naming it: no such device, permission denied (with
// the group to be in), not a video capture device.
std::unique_ptr<V4l2Device> open_v4l2_device(const std::string& path);

struct V4l2Settings {
    int width_px = 1920;  // the driver may give another size: the frames say what it gave
    int height_px = 1080;
    int buffer_count = 4;
    // How long a frame may take before the capture fails (a stalled or starved USB camera).
    std::chrono::milliseconds frame_timeout{5000};
    // Frames dropped after streaming starts, while exposure and white balance settle.
    int frames_to_settle = 2;
};

class V4l2Camera final : public hal::Camera {
  public:
    // Negotiates the format (GREY, then YUYV, then MJPEG) and maps the buffers. Throws
    // std::runtime_error naming the device when it offers none of them or refuses a step.
    V4l2Camera(std::unique_ptr<V4l2Device> device, V4l2Settings settings);
    V4l2Camera(const V4l2Camera&) = delete;
    V4l2Camera& operator=(const V4l2Camera&) = delete;
    ~V4l2Camera() override;

    void start_capture(const hal::CaptureRequest& request) override;
    int completion_fd() const override { return capture_.fd(); }
    hal::CaptureResult take_frames() override;

    std::uint32_t pixel_format() const { return fourcc_; }  // V4L2's fourcc code
    int width_px() const { return width_px_; }
    int height_px() const { return height_px_; }

  private:
    struct Buffer {
        void* address = nullptr;
        std::size_t length = 0;
    };
    hal::CaptureResult capture(const hal::CaptureRequest& request);
    void set_exposure(const hal::CaptureRequest& request);
    hal::Frame to_gray(const Buffer& buffer, std::size_t used_bytes) const;

    std::unique_ptr<V4l2Device> device_;
    V4l2Settings settings_;
    std::uint32_t fourcc_ = 0;
    int width_px_ = 0, height_px_ = 0, stride_bytes_ = 0;
    std::vector<Buffer> buffers_;
    hal::BackgroundJob<hal::CaptureResult> capture_;
};

}  // namespace calbox::drivers
