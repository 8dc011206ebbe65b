#pragma once
// Renders what a camera sees of a planar scene: exact-coverage geometry, then lighting,
// vignetting, defocus and motion blur, sensor noise, 8-bit quantisation and JPEG, all seeded.
#include <cstdint>
#include <vector>

#include "board/sim/camera_reference.hpp"
#include "board/sim/scenes.hpp"

namespace calbox::sim {

struct PhotoSettings {
    int supersample = 4;        // sub-squares per pixel side where an edge crosses it
    double blur_sigma_px = 0;   // defocus, Gaussian
    double noise_sigma_dn = 0;  // sensor noise, Gaussian, in 8-bit counts
    std::uint64_t seed = 1;
    double exposure_dn = 240;      // a white surface (albedo 1) at the image centre
    double lighting_gradient = 0;  // relative change of light across the image
    double lighting_direction_deg = 0;
    double vignetting = 0;  // relative loss of light at the image corners
    // The box or the machine still moving during the exposure: a straight smear of this length.
    double motion_blur_px = 0;
    double motion_blur_direction_deg = 0;
    // Saved as a JPEG at this quality (1-100) and read back, as a camera app delivers it;
    // 0 keeps the sensor's 8-bit values. The Raspberry Pi's still app uses 93.
    int jpeg_quality = 0;
};

struct GrayImage {
    int width_px = 0;
    int height_px = 0;
    std::vector<std::uint8_t> pixels;  // row-major, no padding
};

// The scene's mean albedo over each pixel, before light and sensor (row-major).
std::vector<float> render_albedo(const CameraIntrinsics& camera, const Pose& plane_to_camera,
                                 const Scene& scene);

GrayImage render_photo(const CameraIntrinsics& camera, const Pose& plane_to_camera,
                       const Scene& scene, const PhotoSettings& settings);

}  // namespace calbox::sim
