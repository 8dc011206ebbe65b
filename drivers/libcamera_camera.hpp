#pragma once
// A camera through libcamera (Debian's 0.0.3 API; the Raspberry Pi cameras, and the only way to
// a Pi 5's): still captures and bursts of YUV420 frames whose Y plane is the grey picture,
// buffers mapped once, manual exposure and gain so that the light, not auto-exposure, sets the
// picture. Completions arrive on libcamera's own thread and reach the event loop through an
// eventfd. libcamera's headers stay inside the driver.
#include <memory>
#include <string>

#include "hal/camera.hpp"

namespace calbox::drivers {

struct LibcameraSettings {
    int width_px = 4056;  // the Pi HQ camera's full resolution; libcamera may adjust it
    int height_px = 3040;
    int buffer_count = 2;
};

// Starts libcamera's camera manager and takes its first camera. Throws std::runtime_error with
// one line: "libcamera found no camera", a camera in use by another program, a configuration
// the camera refuses.
std::unique_ptr<hal::Camera> open_libcamera_camera(const LibcameraSettings& settings);

}  // namespace calbox::drivers
