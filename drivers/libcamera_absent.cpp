// The libcamera driver's stand-in for a calbox built with CALBOX_LIBCAMERA=OFF (a box with a USB
// camera only, or a system without libcamera): the rpi board then falls through to V4L2 and
// says why libcamera was not tried.
#include <stdexcept>

#include "drivers/libcamera_camera.hpp"

namespace calbox::drivers {

std::unique_ptr<hal::Camera> open_libcamera_camera(const LibcameraSettings&) {
    throw std::runtime_error("libcamera not built in (CALBOX_LIBCAMERA=OFF)");
}

}  // namespace calbox::drivers
