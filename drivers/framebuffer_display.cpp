#include "drivers/framebuffer_display.hpp"

#include <fcntl.h>
#include <linux/fb.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <stdexcept>

#include "drivers/device_error.hpp"

namespace calbox::drivers {
namespace {

std::uint32_t white_of(const FramebufferFormat& f) {
    auto field = [](FramebufferFormat::Field x) {
        if (x.length <= 0) return std::uint32_t{0};
        return ((std::uint32_t{1} << x.length) - 1U) << x.offset;
    };
    const std::uint32_t white = field(f.red) | field(f.green) | field(f.blue);
    if (white != 0) return white;
    // A palette (8 bpp pseudo-colour) without fields: the last entry, white on the console map.
    return f.bits_per_pixel >= 32 ? 0xFFFFFFFFU : (std::uint32_t{1} << f.bits_per_pixel) - 1U;
}

}  // namespace

std::vector<std::uint8_t> pack_framebuffer(const hal::MonoBitmap& frame,
                                           const FramebufferFormat& f) {
    const int bpp = f.bits_per_pixel;
    if (bpp != 1 && bpp != 8 && bpp != 16 && bpp != 24 && bpp != 32) {
        throw std::invalid_argument("framebuffer depth " + std::to_string(bpp) +
                                    " bits per pixel is not one calbox packs (1, 8, 16, 24, 32)");
    }
    if (f.line_length_bytes * 8 < f.width_px * bpp) {
        throw std::invalid_argument("framebuffer line length is shorter than its width");
    }
    const int scale = std::min(f.width_px / frame.width_px(), f.height_px / frame.height_px());
    if (scale < 1) {
        throw std::invalid_argument("framebuffer " + std::to_string(f.width_px) + "x" +
                                    std::to_string(f.height_px) + " is smaller than the " +
                                    std::to_string(frame.width_px()) + "x" +
                                    std::to_string(frame.height_px()) + " frame");
    }
    const int left = (f.width_px - frame.width_px() * scale) / 2;
    const int top = (f.height_px - frame.height_px() * scale) / 2;
    std::vector<std::uint8_t> screen(
        static_cast<std::size_t>(f.line_length_bytes) * static_cast<std::size_t>(f.height_px), 0);
    const std::uint32_t white = white_of(f);
    for (int y = 0; y < f.height_px; ++y) {
        std::uint8_t* row = screen.data() + static_cast<std::size_t>(y) * f.line_length_bytes;
        for (int x = 0; x < f.width_px; ++x) {
            const int fx = x - left;
            const int fy = y - top;
            const bool lit = fx >= 0 && fy >= 0 && frame.at(fx / scale, fy / scale) &&
                             fx < frame.width_px() * scale && fy < frame.height_px() * scale;
            if (bpp == 1) {
                // Leftmost pixel in the most significant bit, as fbdev's packed mono formats.
                const bool bit = lit != f.mono_one_is_black;
                if (bit) row[x / 8] |= static_cast<std::uint8_t>(0x80U >> (x % 8));
                continue;
            }
            if (!lit) continue;
            const int bytes = bpp / 8;
            for (int b = 0; b < bytes; ++b) {  // little-endian pixels, as fbdev on ARM and x86
                row[x * bytes + b] = static_cast<std::uint8_t>(white >> (8 * b));
            }
        }
    }
    return screen;
}

FramebufferDisplay::FramebufferDisplay(const std::string& device) : device_(device) {
    fd_ = ::open(device.c_str(), O_RDWR | O_CLOEXEC);
    if (fd_ < 0) throw device_error(device, "cannot open");
    fb_var_screeninfo var{};
    fb_fix_screeninfo fix{};
    if (::ioctl(fd_, FBIOGET_VSCREENINFO, &var) < 0 ||
        ::ioctl(fd_, FBIOGET_FSCREENINFO, &fix) < 0) {
        const int why = errno;
        ::close(fd_);
        throw device_error(device, "not a framebuffer", why);
    }
    format_.width_px = static_cast<int>(var.xres);
    format_.height_px = static_cast<int>(var.yres);
    format_.bits_per_pixel = static_cast<int>(var.bits_per_pixel);
    format_.line_length_bytes = static_cast<int>(fix.line_length);
    format_.red = {static_cast<int>(var.red.offset), static_cast<int>(var.red.length)};
    format_.green = {static_cast<int>(var.green.offset), static_cast<int>(var.green.length)};
    format_.blue = {static_cast<int>(var.blue.offset), static_cast<int>(var.blue.length)};
    format_.mono_one_is_black = fix.visual == FB_VISUAL_MONO01;
    try {
        (void)pack_framebuffer(hal::MonoBitmap(128, 64), format_);
    } catch (const std::invalid_argument& e) {
        ::close(fd_);
        throw std::runtime_error(device + ": " + e.what());
    }
}

FramebufferDisplay::~FramebufferDisplay() {
    if (fd_ >= 0) ::close(fd_);
}

void FramebufferDisplay::show(const hal::MonoBitmap& frame) {
    const auto screen = pack_framebuffer(frame, format_);
    std::size_t done = 0;
    while (done < screen.size()) {
        const ssize_t n =
            ::pwrite(fd_, screen.data() + done, screen.size() - done, static_cast<off_t>(done));
        if (n < 0) {
            if (errno == EINTR) continue;
            throw device_error(device_, "write to the framebuffer failed");
        }
        if (n == 0) throw std::runtime_error(device_ + ": the framebuffer is smaller than it said");
        done += static_cast<std::size_t>(n);
    }
}

}  // namespace calbox::drivers
