#pragma once
// Renders what a camera sees of a planar scene: exact-coverage geometry, then lighting,
// vignetting, defocus and motion blur, sensor noise, 8-bit quantisation and JPEG, all seeded.
#include <cstdint>
#include <string>
#include <vector>

#include "board/sim/camera_reference.hpp"
#include "board/sim/scenes.hpp"

namespace calbox::sim {

// The box's own lamp mirrored by a glossy surface in view: a lobe of light around the point where
// the surface turns the lamp towards the camera, Gaussian in the tilt of the half-vector between
// the directions to the lamp and to the camera (Blinn's model). Added to the surface's albedo, so
// a strong lobe saturates whatever lies under it, board squares and holes alike.
struct LampGlare {
    double peak = 0;        // at the lobe's centre, in albedo units (0: a matte surface)
    double spread_deg = 6;  // the lobe's width: a smoother surface mirrors a smaller, sharper spot
    Vec3 lamp_from_camera_mm{60, 0, 0};  // the lamp on the box, in the camera's frame
};

// A surface's glare under the box's lamp, by what it is: "matte" (paper, a burned plate's oxide),
// "laminated" (a printed board in a plastic sleeve), "pei" (a textured or smooth PEI sheet),
// "glass" and "metal" (bare aluminium). Throws std::invalid_argument for another name.
LampGlare glare_of_surface(const std::string& material);

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
    // A lens whose sharpest surface is curved: defocus grows from the centre's blur_sigma_px by
    // this much at the frame's corners, as the square of the distance from the centre.
    double field_curvature_px = 0;
    LampGlare glare;
    // What the camera was asked for, against what exposure_dn holds at: the exposure time's
    // ratio scales the light; the analogue gain scales the light and the sensor's noise.
    double exposure_time_ratio = 1;
    double analogue_gain = 1;
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
