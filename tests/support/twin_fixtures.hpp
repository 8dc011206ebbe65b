#pragma once
// Small pieces the tests share: the box's 12 MP camera, views of rendered images, the core
// camera model of a twin camera.
#include "board/sim/camera_reference.hpp"
#include "board/sim/renderer.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/vision/image_view.hpp"

namespace calbox::test {

// A Raspberry Pi HQ-class 4056x3040 camera: 0.07 mm/px at 400 mm, a mild lens.
inline sim::CameraIntrinsics hq_camera() {
    sim::CameraIntrinsics c;
    c.width_px = 4056;
    c.height_px = 3040;
    c.fx = c.fy = 5700;
    c.cx = 2030.1;
    c.cy = 1517.6;
    c.distortion = {-0.05, 0.08, 0.0002, -0.0001, 0};
    return c;
}

inline vision::GrayView view_of(const sim::GrayImage& image) {
    return {image.pixels.data(), image.width_px, image.height_px, image.width_px};
}

inline geometry::CameraModel as_core(const sim::CameraIntrinsics& c) {
    return sim::as_camera_model(c);
}

}  // namespace calbox::test
