#include "board/sim/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <random>
#include <stdexcept>
#include <thread>

#include "core/vision/image_codec.hpp"

namespace calbox::sim {
namespace {

struct Ray {
    Vec2 on_plane;    // where it meets z = 0
    Vec2 per_height;  // how that point moves per mm above the plane
    bool hits = false;
};

// Every pixel corner's ray direction in the camera (normalized x/z, y/z): (width + 1) by
// (height + 1), row by row. It depends on the lens alone, and undistorting each corner (Newton's
// method) was half of a board photo's time, so it is worked out once per lens.
// (Left uninitialised when made: each is written once, by the worker whose rows it is in; zeroing
// 200 MB first took a core a quarter of a second.)
struct Direction {
    double x, y;
};
struct LensRays {
    CameraIntrinsics camera;
    std::unique_ptr<Direction[]> normalized;
    const Direction* row(int v) const {
        return normalized.get() + static_cast<std::size_t>(v) * (camera.width_px + 1);
    }
};

bool same_lens(const CameraIntrinsics& a, const CameraIntrinsics& b) {
    return a.model == b.model && a.width_px == b.width_px && a.height_px == b.height_px &&
           a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy &&
           a.distortion == b.distortion;
}

// Runs `rows(first, end)` over [0, count) split among the machine's cores.
template <typename Rows>
void on_all_cores(int count, const Rows& rows) {
    const int workers = std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 8);
    const int each = (count + workers - 1) / workers;
    std::vector<std::thread> threads;
    for (int w = 0; w < workers; ++w) {
        const int first = w * each, end = std::min(count, first + each);
        if (first >= end) break;
        threads.emplace_back([&rows, first, end] { rows(first, end); });
    }
    for (auto& t : threads) t.join();
}

// The last lens's rays, kept: a twin photographs with one camera, many times (a 12 MP camera's
// take 200 MB, so only the last is kept).
std::shared_ptr<const LensRays> rays_of(const CameraIntrinsics& camera) {
    static std::mutex mutex;
    static std::shared_ptr<const LensRays> last;
    {
        const std::lock_guard lock(mutex);
        if (last && same_lens(last->camera, camera)) return last;
    }
    auto rays = std::make_shared<LensRays>();
    rays->camera = camera;
    rays->normalized = std::make_unique_for_overwrite<Direction[]>(
        static_cast<std::size_t>(camera.width_px + 1) * (camera.height_px + 1));
    on_all_cores(camera.height_px + 1, [&](int first, int end) {
        for (int v = first; v < end; ++v) {
            Direction* out =
                rays->normalized.get() + static_cast<std::size_t>(v) * (camera.width_px + 1);
            // Each corner's Newton starts from the line through its two left neighbours: within
            // a few 1e-9 of the answer, it converges in one step where a cold start took five.
            Vec2 guess = undistort_pixel(camera, 0, v);
            for (int u = 0; u <= camera.width_px; ++u) {
                if (u == 1) guess = {out[0].x, out[0].y};
                if (u >= 2)
                    guess = {2 * out[u - 1].x - out[u - 2].x, 2 * out[u - 1].y - out[u - 2].y};
                const Vec2 n = u == 0 ? guess : undistort_pixel_from(camera, u, v, guess);
                out[u] = {n.x, n.y};
            }
        }
    });
    const std::lock_guard lock(mutex);
    last = rays;
    return last;
}

void trace_row(const LensRays& rays, const Mat3& camera_to_plane, const Vec3& origin, int v,
               std::vector<Ray>& row) {
    const int width = rays.camera.width_px;
    row.resize(static_cast<std::size_t>(width) + 1);
    const Direction* normalized = rays.row(v);
    for (int u = 0; u <= width; ++u) {
        const Direction n = normalized[u];
        const Vec3 d = camera_to_plane * Vec3{n.x, n.y, 1.0};
        Ray& r = row[static_cast<std::size_t>(u)];
        r.hits = d.z * origin.z < 0;  // the ray heads towards the plane
        if (!r.hits) continue;
        const double s = -origin.z / d.z;
        r.on_plane = {origin.x + d.x * s, origin.y + d.y * s};
        r.per_height = {d.x / d.z, d.y / d.z};
    }
}

// Where the box's lamp stands and how wide its mirrored lobe is, in the plane's frame.
struct GlareGeometry {
    Vec3 lamp_mm;
    Vec3 camera_mm;
    double spread_rad;
    double peak;
};

// The glare lobe (0..1) at a point of the plane (z = 0): the half-vector between the directions to
// the lamp and to the camera, against the plane's normal on the camera's side.
double glare_lobe(const GlareGeometry& g, Vec2 p) {
    const Vec3 to_camera{g.camera_mm.x - p.x, g.camera_mm.y - p.y, g.camera_mm.z};
    const Vec3 to_lamp{g.lamp_mm.x - p.x, g.lamp_mm.y - p.y, g.lamp_mm.z};
    if (to_lamp.z * to_camera.z <= 0) return 0;  // the lamp lights the plane's other face
    const Vec3 half = to_camera * (1 / to_camera.norm()) + to_lamp * (1 / to_lamp.norm());
    const double tilt = std::acos(std::min(1.0, std::abs(half.z) / half.norm()));
    return std::exp(-0.5 * tilt * tilt / (g.spread_rad * g.spread_rad));
}

void render_rows(const LensRays& rays, const Pose& pose, const Scene& scene,
                 const GlareGeometry* glare, int first_row, int end_row,
                 std::vector<float>& albedo) {
    const Mat3 camera_to_plane = pose.rotation.transposed();
    const Vec3 origin = pose.camera_centre_in_plane();
    std::vector<Ray> here, below;
    trace_row(rays, camera_to_plane, origin, first_row, here);
    for (int v = first_row; v < end_row; ++v) {
        trace_row(rays, camera_to_plane, origin, v + 1, below);
        float* out = albedo.data() + static_cast<std::size_t>(v) * rays.camera.width_px;
        for (int u = 0; u < rays.camera.width_px; ++u) {
            const Ray& r = here[static_cast<std::size_t>(u)];
            const Ray& right = here[static_cast<std::size_t>(u) + 1];
            const Ray& down = below[static_cast<std::size_t>(u)];
            double a = 0;  // a ray that misses the plane sees black
            if (r.hits && right.hits && down.hits) {
                const Footprint f{
                    r.on_plane,
                    {{right.on_plane.x - r.on_plane.x, down.on_plane.x - r.on_plane.x},
                     {right.on_plane.y - r.on_plane.y, down.on_plane.y - r.on_plane.y}},
                    r.per_height};
                a = scene.albedo(f);
                if (glare != nullptr) a += glare->peak * glare_lobe(*glare, r.on_plane);
            }
            out[u] = static_cast<float>(a);
        }
        std::swap(here, below);
    }
}

// A straight smear of `length_px` along `direction_deg`: the line's weight spread bilinearly
// over the kernel's pixels, so that sub-pixel lengths and any angle are represented.
cv::Mat motion_kernel(double length_px, double direction_deg) {
    const int half = static_cast<int>(std::ceil(length_px / 2)) + 1;
    cv::Mat kernel = cv::Mat::zeros(2 * half + 1, 2 * half + 1, CV_32F);
    const double c = std::cos(radians(direction_deg)), s = std::sin(radians(direction_deg));
    const int samples = 64;
    for (int i = 0; i < samples; ++i) {
        const double t = ((i + 0.5) / samples - 0.5) * length_px;
        const double x = half + t * c, y = half + t * s;
        const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
        const double fx = x - x0, fy = y - y0;
        kernel.at<float>(y0, x0) += static_cast<float>((1 - fx) * (1 - fy));
        kernel.at<float>(y0, x0 + 1) += static_cast<float>(fx * (1 - fy));
        kernel.at<float>(y0 + 1, x0) += static_cast<float>((1 - fx) * fy);
        kernel.at<float>(y0 + 1, x0 + 1) += static_cast<float>(fx * fy);
    }
    return kernel / static_cast<double>(samples);
}

// Defocus that grows from `centre_sigma_px` at the image centre by `corner_extra_px` at its
// corners, as the square of the radius (a lens's curved field). Between layers blurred at evenly
// spaced sigmas, each pixel takes the two whose sigmas bracket its own, weighted linearly; two
// layers are held at a time.
void blur_growing_to_corners(cv::Mat& radiance, double centre_sigma_px, double corner_extra_px) {
    const auto blurred = [&](double sigma) {
        cv::Mat out;
        if (sigma > 0)
            cv::GaussianBlur(radiance, out, cv::Size(0, 0), sigma, 0, cv::BORDER_REFLECT);
        else
            out = radiance.clone();
        return out;
    };
    // Layers half a pixel of sigma apart: a blend of neighbours then stands for the blur between
    // to within a few hundredths of a count on a step edge.
    const int layers = std::clamp(static_cast<int>(std::ceil(corner_extra_px / 0.5)), 1, 32);
    const double half_w = (radiance.cols - 1) / 2.0, half_h = (radiance.rows - 1) / 2.0;
    const double corner_sq = half_w * half_w + half_h * half_h;
    cv::Mat out(radiance.size(), CV_32F);
    cv::Mat lower = blurred(centre_sigma_px);
    for (int k = 0; k < layers; ++k) {
        const cv::Mat upper = blurred(centre_sigma_px + corner_extra_px * (k + 1) / layers);
        for (int v = 0; v < radiance.rows; ++v) {
            const float* a = lower.ptr<float>(v);
            const float* b = upper.ptr<float>(v);
            float* o = out.ptr<float>(v);
            const double dv = v - half_h;
            for (int u = 0; u < radiance.cols; ++u) {
                const double du = u - half_w;
                const double t = (du * du + dv * dv) / corner_sq * layers - k;
                if (t < 0 || t > 1 || (t == 0 && k > 0)) continue;  // another pair's pixel
                o[u] = static_cast<float>((1 - t) * a[u] + t * b[u]);
            }
        }
        lower = upper;
    }
    out.copyTo(radiance);  // into the buffer the caller reads: radiance may wrap it
}

}  // namespace

LampGlare glare_of_surface(const std::string& material) {
    // Peaks and widths chosen so that, with the lamp 60 mm beside a camera 300-450 mm away, a
    // laminated board's or a glass bed's spot saturates at the exposure a matte white takes
    // (about a tenth of the frame for the board), PEI's is a broad sheen that saturates little,
    // and bare metal's is broad and bright.
    struct Surface {
        const char* name;
        LampGlare glare;
    };
    static const Surface surfaces[] = {{"matte", {0, 6, {60, 0, 0}}},
                                       {"laminated", {1.2, 6, {60, 0, 0}}},
                                       {"pei", {0.45, 12, {60, 0, 0}}},
                                       {"glass", {3.0, 2, {60, 0, 0}}},
                                       {"metal", {0.9, 10, {60, 0, 0}}}};
    std::string names;
    for (const auto& surface : surfaces) {
        if (material == surface.name) return surface.glare;
        names += names.empty() ? surface.name : std::string(", ") + surface.name;
    }
    throw std::invalid_argument("unknown surface \"" + material + "\" (one of " + names + ")");
}

namespace {

// The scene's albedo over each pixel, with the lamp's glare added where `glare` has a peak.
std::vector<float> render_surface(const CameraIntrinsics& camera, const Pose& plane_to_camera,
                                  const Scene& scene, const LampGlare& glare) {
    if (camera.width_px <= 0 || camera.height_px <= 0 || camera.width_px > 20000 ||
        camera.height_px > 20000) {
        throw std::invalid_argument("camera size must be 1..20000 px on each side");
    }
    if (glare.peak < 0 || !(glare.spread_deg > 0))
        throw std::invalid_argument("a lamp's glare needs a peak >= 0 and a spread above 0 deg");
    std::optional<GlareGeometry> lobe;
    if (glare.peak > 0) {
        const Vec3 camera_mm = plane_to_camera.camera_centre_in_plane();
        lobe = GlareGeometry{
            camera_mm + plane_to_camera.rotation.transposed() * glare.lamp_from_camera_mm,
            camera_mm, radians(glare.spread_deg), glare.peak};
    }
    std::vector<float> albedo(static_cast<std::size_t>(camera.width_px) * camera.height_px);
    const auto rays = rays_of(camera);
    on_all_cores(camera.height_px, [&](int first, int end) {
        render_rows(*rays, plane_to_camera, scene, lobe ? &*lobe : nullptr, first, end, albedo);
    });
    return albedo;
}

}  // namespace

std::vector<float> render_albedo(const CameraIntrinsics& camera, const Pose& plane_to_camera,
                                 const Scene& scene) {
    return render_surface(camera, plane_to_camera, scene, {});
}

GrayImage render_photo(const CameraIntrinsics& camera, const Pose& plane_to_camera,
                       const Scene& scene, const PhotoSettings& settings) {
    // Albedo becomes light on the sensor in place, in 8-bit counts before noise.
    if (!(settings.exposure_time_ratio > 0) || !(settings.analogue_gain > 0))
        throw std::invalid_argument("an exposure time and a gain must be above 0");
    std::vector<float> light_dn = render_surface(camera, plane_to_camera, scene, settings.glare);
    const double exposed_dn =
        settings.exposure_dn * settings.exposure_time_ratio * settings.analogue_gain;
    cv::Mat radiance(camera.height_px, camera.width_px, CV_32F, light_dn.data());
    const double half_w = camera.width_px / 2.0, half_h = camera.height_px / 2.0;
    const double corner = std::hypot(half_w, half_h);
    const double cos_l = std::cos(radians(settings.lighting_direction_deg));
    const double sin_l = std::sin(radians(settings.lighting_direction_deg));
    // The light's slope across the image, column by column (the same figures, worked out once).
    std::vector<double> across(static_cast<std::size_t>(camera.width_px));
    for (std::size_t u = 0; u < across.size(); ++u) {
        across[u] = (static_cast<double>(u) - half_w) / camera.width_px * cos_l;
    }
    // The vignette of a row, column by column. Rows v and height - v lie equally far from the
    // centre, as do columns u and width - u (the offsets are exact halves): each distance's hypot
    // is worked out once for all four, the same figures (hypot is even in each argument).
    std::vector<double> vignette(across.size(), 1.0);  // 1 - 0 * rho^2, without the square root
    const auto vignette_of_row = [&](int v) {
        for (int u = camera.width_px - 1; u >= 0; --u) {
            const int mirror = camera.width_px - u;
            if (mirror > u && mirror < camera.width_px) {
                vignette[static_cast<std::size_t>(u)] = vignette[static_cast<std::size_t>(mirror)];
                continue;
            }
            const double rho = std::hypot(u - half_w, v - half_h) / corner;
            vignette[static_cast<std::size_t>(u)] = 1 - settings.vignetting * rho * rho;
        }
    };
    const auto light_row = [&](int v) {
        float* row = radiance.ptr<float>(v);
        const double down = (v - half_h) / camera.height_px * sin_l;
        for (int u = 0; u < camera.width_px; ++u) {
            const auto i = static_cast<std::size_t>(u);
            const double light = 1 + settings.lighting_gradient * (across[i] + down);
            row[u] = static_cast<float>(row[u] * exposed_dn * light * vignette[i]);
        }
    };
    for (int v = 0; v < camera.height_px; ++v) {
        const int mirror = camera.height_px - v;
        if (mirror < v) continue;  // lit with its mirror, above
        if (settings.vignetting != 0) vignette_of_row(v);
        light_row(v);
        if (mirror > v && mirror < camera.height_px) light_row(mirror);
    }
    if (settings.field_curvature_px > 0) {
        blur_growing_to_corners(radiance, settings.blur_sigma_px, settings.field_curvature_px);
    } else if (settings.blur_sigma_px > 0) {
        cv::GaussianBlur(radiance, radiance, cv::Size(0, 0), settings.blur_sigma_px, 0,
                         cv::BORDER_REFLECT);
    }
    if (settings.motion_blur_px > 0) {
        cv::filter2D(radiance, radiance, -1,
                     motion_kernel(settings.motion_blur_px, settings.motion_blur_direction_deg),
                     cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
    }
    GrayImage image{camera.width_px, camera.height_px, {}};
    image.pixels.resize(light_dn.size());
    std::mt19937_64 rng(settings.seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    const bool noisy = settings.noise_sigma_dn > 0;
    const double noise_dn = settings.noise_sigma_dn * settings.analogue_gain;
    for (std::size_t i = 0; i < light_dn.size(); ++i) {
        double dn = light_dn[i];
        if (noisy) dn += noise_dn * noise(rng);
        image.pixels[i] = static_cast<std::uint8_t>(std::clamp(std::lround(dn), 0L, 255L));
    }
    if (settings.jpeg_quality > 0) {
        if (settings.jpeg_quality > 100) throw std::invalid_argument("JPEG quality is 1..100");
        const auto file = vision::jpeg_bytes(
            {image.pixels.data(), image.width_px, image.height_px, image.width_px, 1},
            settings.jpeg_quality);
        auto decoded = vision::decode_gray(file);
        if (decoded.width_px != image.width_px || decoded.height_px != image.height_px)
            throw std::runtime_error("the JPEG round trip lost the picture");
        image.pixels = std::move(decoded.pixels);
    }
    return image;
}

}  // namespace calbox::sim
