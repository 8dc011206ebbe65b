#include "board/sim/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>
#include <thread>

namespace calbox::sim {
namespace {

struct Ray {
    Vec2 on_plane;       // where it meets z = 0
    Vec2 per_height;     // how that point moves per mm above the plane
    bool hits = false;
};

void trace_row(const CameraIntrinsics& camera, const Mat3& camera_to_plane, const Vec3& origin,
               int v, std::vector<Ray>& row) {
    row.resize(static_cast<std::size_t>(camera.width_px) + 1);
    for (int u = 0; u <= camera.width_px; ++u) {
        const Vec2 n = undistort_pixel(camera, u, v);
        const Vec3 d = camera_to_plane * Vec3{n.x, n.y, 1.0};
        Ray& r = row[static_cast<std::size_t>(u)];
        r.hits = d.z * origin.z < 0;  // the ray heads towards the plane
        if (!r.hits) continue;
        const double s = -origin.z / d.z;
        r.on_plane = {origin.x + d.x * s, origin.y + d.y * s};
        r.per_height = {d.x / d.z, d.y / d.z};
    }
}

void render_rows(const CameraIntrinsics& camera, const Pose& pose, const Scene& scene,
                 const PhotoSettings& settings, int first_row, int end_row, cv::Mat& radiance) {
    const Mat3 camera_to_plane = pose.rotation.transposed();
    const Vec3 origin = pose.camera_centre_in_plane();
    std::vector<Ray> here, below;
    trace_row(camera, camera_to_plane, origin, first_row, here);
    const double half_w = camera.width_px / 2.0, half_h = camera.height_px / 2.0;
    const double corner = std::hypot(half_w, half_h);
    const double cos_l = std::cos(radians(settings.lighting_direction_deg));
    const double sin_l = std::sin(radians(settings.lighting_direction_deg));
    for (int v = first_row; v < end_row; ++v) {
        trace_row(camera, camera_to_plane, origin, v + 1, below);
        float* out = radiance.ptr<float>(v);
        for (int u = 0; u < camera.width_px; ++u) {
            const Ray& r = here[static_cast<std::size_t>(u)];
            const Ray& right = here[static_cast<std::size_t>(u) + 1];
            const Ray& down = below[static_cast<std::size_t>(u)];
            double albedo = 0;
            if (r.hits && right.hits && down.hits) {
                Footprint f{r.on_plane,
                            {{right.on_plane.x - r.on_plane.x, down.on_plane.x - r.on_plane.x},
                             {right.on_plane.y - r.on_plane.y, down.on_plane.y - r.on_plane.y}},
                            r.per_height};
                albedo = scene.albedo(f);
            }
            const double light = 1 + settings.lighting_gradient *
                                         ((u - half_w) / camera.width_px * cos_l +
                                          (v - half_h) / camera.height_px * sin_l);
            const double rho = std::hypot(u - half_w, v - half_h) / corner;
            const double vignette = 1 - settings.vignetting * rho * rho;
            out[u] = static_cast<float>(albedo * settings.exposure_dn * light * vignette);
        }
        std::swap(here, below);
    }
}

}  // namespace

GrayImage render_photo(const CameraIntrinsics& camera, const Pose& plane_to_camera,
                       const Scene& scene, const PhotoSettings& settings) {
    if (camera.width_px <= 0 || camera.height_px <= 0 || camera.width_px > 20000 ||
        camera.height_px > 20000) {
        throw std::invalid_argument("camera size must be 1..20000 px on each side");
    }
    cv::Mat radiance(camera.height_px, camera.width_px, CV_32F);
    const int workers = std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 8);
    std::vector<std::thread> threads;
    const int rows_each = (camera.height_px + workers - 1) / workers;
    for (int w = 0; w < workers; ++w) {
        const int first = w * rows_each, end = std::min(camera.height_px, first + rows_each);
        if (first >= end) break;
        threads.emplace_back([&, first, end] {
            render_rows(camera, plane_to_camera, scene, settings, first, end, radiance);
        });
    }
    for (auto& t : threads) t.join();

    if (settings.blur_sigma_px > 0) {
        cv::GaussianBlur(radiance, radiance, cv::Size(0, 0), settings.blur_sigma_px, 0,
                         cv::BORDER_REFLECT);
    }
    GrayImage image{camera.width_px, camera.height_px, {}};
    image.pixels.resize(static_cast<std::size_t>(camera.width_px) * camera.height_px);
    std::mt19937_64 rng(settings.seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    const bool noisy = settings.noise_sigma_dn > 0;
    for (int v = 0; v < camera.height_px; ++v) {
        const float* in = radiance.ptr<float>(v);
        std::uint8_t* out = image.pixels.data() + static_cast<std::size_t>(v) * camera.width_px;
        for (int u = 0; u < camera.width_px; ++u) {
            double dn = in[u];
            if (noisy) dn += settings.noise_sigma_dn * noise(rng);
            out[u] = static_cast<std::uint8_t>(std::clamp(std::lround(dn), 0L, 255L));
        }
    }
    return image;
}

}  // namespace calbox::sim
