#pragma once
// The Linux framebuffer (/dev/fbN) as the box's display: the 128x64 frame scaled by the largest
// whole factor that fits, centred, lit pixels white, at whatever depth the device reports.
#include <cstdint>
#include <string>
#include <vector>

#include "hal/display.hpp"

namespace calbox::drivers {

struct FramebufferFormat {
    int width_px = 0;
    int height_px = 0;
    int bits_per_pixel = 0;  // 1, 8, 16, 24 or 32
    int line_length_bytes = 0;
    struct Field {
        int offset = 0;
        int length = 0;
    };
    Field red, green, blue;
    bool mono_one_is_black = false;  // FB_VISUAL_MONO01
};

// The bytes of the whole visible screen for one frame, row after row of line_length_bytes.
// Throws std::invalid_argument for a depth it cannot pack or a screen smaller than the frame.
std::vector<std::uint8_t> pack_framebuffer(const hal::MonoBitmap& frame,
                                           const FramebufferFormat& format);

class FramebufferDisplay final : public hal::Display {
  public:
    // Throws std::runtime_error naming the device: missing, permission denied, not a
    // framebuffer, a depth or size it cannot show.
    explicit FramebufferDisplay(const std::string& device);
    FramebufferDisplay(const FramebufferDisplay&) = delete;
    FramebufferDisplay& operator=(const FramebufferDisplay&) = delete;
    ~FramebufferDisplay() override;
    int width_px() const override { return 128; }
    int height_px() const override { return 64; }
    void show(const hal::MonoBitmap& frame) override;  // one write of the whole screen
    const FramebufferFormat& format() const { return format_; }

  private:
    std::string device_;
    int fd_ = -1;
    FramebufferFormat format_;
};

}  // namespace calbox::drivers
