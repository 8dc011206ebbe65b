#pragma once
// What the firmware needs of a camera: start a capture, learn on a file descriptor that it
// finished, then take the frames. Slow work never blocks the caller's event loop.
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace calbox::hal {

enum class PixelFormat { gray8, rgb888 };

struct FrameMetadata {
    std::chrono::microseconds exposure{0};
    double analogue_gain = 1.0;
    std::chrono::nanoseconds timestamp{0};  // sensor timestamp, monotonic clock
    std::uint64_t sequence = 0;
};

struct Frame {
    int width_px = 0;
    int height_px = 0;
    int stride_bytes = 0;
    PixelFormat format = PixelFormat::gray8;
    std::vector<std::uint8_t> pixels;
    FrameMetadata metadata;
};

struct CaptureRequest {
    int frame_count = 1;                                // 1 is a single shot, more is a burst
    std::optional<std::chrono::microseconds> exposure;  // unset: automatic
    std::optional<double> analogue_gain;                // unset: automatic
};

struct CaptureResult {
    std::vector<Frame> frames;
    std::string error;  // empty on success
    bool ok() const { return error.empty(); }
};

class Camera {
  public:
    virtual ~Camera() = default;
    // Starts a capture; throws std::logic_error if one is already running.
    virtual void start_capture(const CaptureRequest& request) = 0;
    // Readable once the capture started last has completed or failed.
    virtual int completion_fd() const = 0;
    // Takes the finished capture's frames (or its error) and clears the completion.
    virtual CaptureResult take_frames() = 0;
};

}  // namespace calbox::hal
