// The twin's photos at the edge of what the box measures: edges where the geometry puts them,
// the sensor's noise and response, the harder photos (highlights, blur, dim light), the lamp and
// the lens, and the photos kept between runs.
#include "tests/unit/renderer_checks.hpp"

TEST_GROUP(EdgeTruth){};

namespace {

// Where the projection of the plane line p(t) = a + t (b - a), t in [0, 1], crosses image row
// `v` (or column, when `column` is set), found by bisection on t.
Vec2 projected_crossing(const CameraIntrinsics& c, const Pose& pose, Vec3 a, Vec3 b, double at,
                        bool column) {
    double lo = 0, hi = 1;
    const auto coordinate = [&](double t) {
        const Vec2 px = project_point(c, pose, a + (b - a) * t);
        return column ? px.x : px.y;
    };
    const bool rising = coordinate(hi) > coordinate(lo);
    for (int i = 0; i < 100; ++i) {
        const double mid = (lo + hi) / 2;
        if ((coordinate(mid) < at) == rising)
            lo = mid;
        else
            hi = mid;
    }
    return project_point(c, pose, a + (b - a) * lo);
}

}  // namespace

TEST(EdgeTruth, board_edges_lie_where_the_camera_projects_them_to_a_hundredth_of_a_pixel) {
    const CameraIntrinsics camera = pinhole_1080p();
    const Pose pose = board_pose(80, 50, 10, 400);
    const BoardScene scene(geometry::parse_pattern_spec("chessboard:9x6@20"), 4);
    const auto albedo = render_albedo(camera, pose, scene);
    const auto at = [&](int u, int v) {
        return static_cast<double>(albedo[static_cast<std::size_t>(v) * camera.width_px + u]);
    };
    double worst = 0;
    // Rows across the line x = 140 mm between board rows y = 42 and 58 mm (away from corners),
    // slanted in the image by the tilt and the lens.
    const Vec2 top = project_point(camera, pose, {140, 42, 0}),
               bottom = project_point(camera, pose, {140, 58, 0});
    for (int v = static_cast<int>(std::ceil(std::min(top.y, bottom.y)));
         v <= std::floor(std::max(top.y, bottom.y)); ++v) {
        const Vec2 edge = projected_crossing(camera, pose, {140, 30, 0}, {140, 70, 0}, v, false);
        const int u0 = static_cast<int>(edge.x) - 12, u1 = static_cast<int>(edge.x) + 12;
        double sum = 0;
        for (int u = u0; u <= u1; ++u) sum += (at(u, v) - at(u1, v)) / (at(u0, v) - at(u1, v));
        worst = std::max(worst, std::abs(u0 - 0.5 + sum - edge.x));
    }
    CHECK_TEXT(worst < 0.01, ("worst board edge error " + std::to_string(worst) + " px").c_str());
}

TEST(EdgeTruth, stroke_edges_lie_where_the_camera_projects_them_to_a_hundredth_of_a_pixel) {
    CameraIntrinsics camera;
    camera.width_px = 900;
    camera.height_px = 700;
    camera.fx = camera.fy = 5700;
    camera.cx = 451.3;
    camera.cy = 347.9;
    camera.distortion = {-0.05, 0.08, 0.0003, -0.0002, 0};
    const Pose pose = look_at_pose({10, -35, 400}, {0, 0, 0}, 3);
    const double half_width = 0.225, top_z = 0.2;
    const StrokeScene scene({{{-10, 0, top_z}, {10, 0, top_z}, 2 * half_width}}, 0.08, 0.85, 4);
    const auto albedo = render_albedo(camera, pose, scene);
    const auto coverage = [&](int u, int v) {
        return (albedo[static_cast<std::size_t>(v) * camera.width_px + u] - 0.08) / (0.85 - 0.08);
    };
    double worst = 0;
    const Vec2 left = project_point(camera, pose, {-8, 0, top_z}),
               right = project_point(camera, pose, {8, 0, top_z});
    for (int u = static_cast<int>(left.x); u <= static_cast<int>(right.x); u += 7) {
        // The material's upper edge (bed +y is image up) and lower edge in this column.
        const Vec2 upper = projected_crossing(camera, pose, {-10, half_width, top_z},
                                              {10, half_width, top_z}, u, true);
        const Vec2 lower = projected_crossing(camera, pose, {-10, -half_width, top_z},
                                              {10, -half_width, top_z}, u, true);
        const int inside = static_cast<int>(std::lround((upper.y + lower.y) / 2));
        double above = 0, below = 0;
        for (int v = inside - 15; v < inside; ++v) above += coverage(u, v);
        for (int v = inside; v <= inside + 15; ++v) below += coverage(u, v);
        worst = std::max(worst, std::abs((inside - 0.5 - above) - upper.y));
        worst = std::max(worst, std::abs((inside - 0.5 + below) - lower.y));
    }
    CHECK_TEXT(worst < 0.01, ("worst stroke edge error " + std::to_string(worst) + " px").c_str());
}

TEST_GROUP(SensorModel){};

TEST(SensorModel, noise_is_seeded_and_has_the_asked_spread_light_falls_off_as_asked) {
    CameraIntrinsics camera;
    camera.width_px = 400;
    camera.height_px = 300;
    camera.fx = camera.fy = 1000;
    camera.cx = 199.5;
    camera.cy = 149.5;
    const Pose pose = look_at_pose({0, 0, 400}, {0, 0, 0}, 0);
    const StrokeScene bare_bed({}, 0.5, 0.85, 4);  // nothing printed: a flat grey field
    PhotoSettings photo;
    photo.exposure_dn = 200;
    photo.noise_sigma_dn = 2.0;
    photo.seed = 11;
    const GrayImage a = render_photo(camera, pose, bare_bed, photo);
    const GrayImage b = render_photo(camera, pose, bare_bed, photo);
    CHECK(a.pixels == b.pixels);
    photo.seed = 12;
    CHECK(render_photo(camera, pose, bare_bed, photo).pixels != a.pixels);
    const auto [mean, spread] = mean_and_spread(a);
    DOUBLES_EQUAL(100.0, mean, 0.05);
    // Gaussian noise of 2 DN, then rounding (adds 1/12 DN^2 of variance).
    DOUBLES_EQUAL(std::sqrt(4.0 + 1.0 / 12), spread, 0.05);

    PhotoSettings shaded;
    shaded.exposure_dn = 200;
    shaded.vignetting = 0.2;
    shaded.lighting_gradient = 0.1;  // along +x: the right edge gets 10 % more than the left
    const GrayImage s = render_photo(camera, pose, bare_bed, shaded);
    const auto at = [&](int u, int v) {
        return static_cast<double>(s.pixels[static_cast<std::size_t>(v) * 400 + u]);
    };
    DOUBLES_EQUAL(100.0, at(200, 150), 1.0);
    // Corner pixel (0, 0): light 1 + 0.1 * (-0.5 - 0.5 * 0) = 0.95, vignette 1 - 0.2 * rho^2 ~ 0.8.
    DOUBLES_EQUAL(100.0 * 0.95 * 0.8, at(0, 0), 1.0);
    CHECK(at(399, 150) - at(0, 150) > 8.0);
}

// The harder twin's troubles (issue 12), each against a hand-worked value.
TEST_GROUP(HarderPhotos){};

TEST(HarderPhotos, gloss_shines_where_a_round_strand_turns_the_lamp_to_the_camera) {
    const auto camera = overhead_camera();
    const Pose pose = look_at_pose({0, 0, 400}, {0, 0, 0}, 0);
    StrokeSurface glossy;
    glossy.gloss = 0.5;
    glossy.light_azimuth_deg = 0;  // from +x
    glossy.light_elevation_deg = 30;
    // Half vector of the lamp (cos 30, 0, sin 30) and the camera (0, 0, 1): (1/2, 0, sqrt(3)/2),
    // which a round strand's normal meets half-way out of its half-width towards the lamp: a
    // 4 mm strand along y shines at x = +1 mm.
    const StrokeScene across({{{0, -40, 0}, {0, 40, 0}, 4.0}}, 0.08, 0.60, 4, 1.0, glossy);
    const auto [at_mm, peak] = highlight_across_row(render_albedo(camera, pose, across), 150, 0.60);
    DOUBLES_EQUAL(1.0, at_mm, 0.1);
    CHECK(peak > 0.2);
    // A strand along the lamp's direction cannot lean towards it: its top, 30 degrees off the
    // half vector, hardly shines.
    const StrokeScene along({{{-40, 0, 0}, {40, 0, 0}, 4.0}}, 0.08, 0.60, 4, 1.0, glossy);
    const auto albedo = render_albedo(camera, pose, along);
    double brightest = 0;
    for (int v = 140; v < 160; ++v)
        brightest = std::max(brightest,
                             static_cast<double>(albedo[static_cast<std::size_t>(v) * 400 + 200]));
    CHECK(brightest - 0.60 < 0.05 * peak);
}

TEST(HarderPhotos, a_textured_bed_keeps_its_mean_albedo_and_varies_by_the_asked_swing) {
    const auto camera = overhead_camera();
    const Pose pose = look_at_pose({0, 0, 400}, {0, 0, 0}, 0);
    StrokeSurface grain;
    grain.bed_texture = 0.3;
    grain.bed_texture_grain_mm = 2.0;  // five pixels: resolved
    const auto albedo = render_albedo(camera, pose, StrokeScene({}, 0.5, 0.85, 4, 1.0, grain));
    double sum = 0, sum2 = 0, low = 1, high = 0;
    for (const float a : albedo) {
        sum += a;
        sum2 += static_cast<double>(a) * a;
        low = std::min(low, static_cast<double>(a));
        high = std::max(high, static_cast<double>(a));
    }
    const double n = static_cast<double>(albedo.size());
    const double mean = sum / n, spread = std::sqrt(sum2 / n - mean * mean);
    DOUBLES_EQUAL(0.5, mean, 0.01);
    // Value noise uniform in [-1, 1] at the lattice, smoothed: a spread of 0.1-0.2 of the swing.
    CHECK_TEXT(spread > 0.5 * 0.3 * 0.1 && spread < 0.5 * 0.3 * 0.4,
               std::to_string(spread).c_str());
    CHECK(low >= 0.5 * 0.7 - 1e-6 && high <= 0.5 * 1.3 + 1e-6);
    CHECK(render_albedo(camera, pose, StrokeScene({}, 0.5, 0.85, 4, 1.0, grain)) == albedo);
}

TEST(HarderPhotos, motion_blur_ramps_an_edge_across_its_length_and_keeps_the_light) {
    const auto camera = overhead_camera();
    const Pose pose = look_at_pose({0, 0, 400}, {0, 0, 0}, 0);
    // A 40 mm band along y: two sharp vertical edges at x = -20 and +20 mm.
    const StrokeScene band({{{0, -100, 0}, {0, 100, 0}, 40.0}}, 0.1, 0.9, 4);
    PhotoSettings sharp;
    sharp.exposure_dn = 200;
    PhotoSettings smeared = sharp;
    smeared.motion_blur_px = 8;
    const auto mean_of = [](const GrayImage& image) {
        double sum = 0;
        for (const auto p : image.pixels) sum += p;
        return sum / static_cast<double>(image.pixels.size());
    };
    // The 10-90 % rise of a straight smear of length L over a sharp edge is 0.8 L.
    const auto rise_px = [](const GrayImage& image) {
        const auto* row = &image.pixels[150 * 400];
        const double low = row[100], high = row[200];
        int first = -1, last = -1;
        for (int u = 100; u < 200; ++u) {
            if (first < 0 && row[u] > low + 0.1 * (high - low)) first = u;
            if (last < 0 && row[u] >= low + 0.9 * (high - low)) last = u;
        }
        return last - first;
    };
    const GrayImage a = render_photo(camera, pose, band, sharp);
    const GrayImage b = render_photo(camera, pose, band, smeared);
    DOUBLES_EQUAL(mean_of(a), mean_of(b), 0.5);
    CHECK(rise_px(a) <= 1);
    DOUBLES_EQUAL(0.8 * 8, rise_px(b), 1.0);
    smeared.motion_blur_direction_deg = 90;  // along the edge: it stays sharp
    CHECK(rise_px(render_photo(camera, pose, band, smeared)) <= 1);
}

TEST(HarderPhotos, jpeg_at_the_camera_apps_quality_changes_pixels_by_a_few_counts) {
    const auto camera = overhead_camera();
    const Pose pose = look_at_pose({0, 0, 400}, {0, 0, 0}, 0);
    const StrokeScene strokes(
        {{{-30, -20, 0}, {30, 25, 0}, 1.2}, {{-30, 20, 0}, {30, -10, 0}, 0.8}}, 0.08, 0.85, 4);
    PhotoSettings raw;
    raw.noise_sigma_dn = 2;
    raw.blur_sigma_px = 0.7;
    const GrayImage sensor = render_photo(camera, pose, strokes, raw);
    const auto rms_from_sensor = [&](int quality) {
        PhotoSettings jpeg = raw;
        jpeg.jpeg_quality = quality;
        const GrayImage image = render_photo(camera, pose, strokes, jpeg);
        double sum = 0;
        for (std::size_t i = 0; i < image.pixels.size(); ++i) {
            const double d = static_cast<double>(image.pixels[i]) - sensor.pixels[i];
            sum += d * d;
        }
        return std::sqrt(sum / static_cast<double>(image.pixels.size()));
    };
    const double q93 = rms_from_sensor(93), q50 = rms_from_sensor(50);
    CHECK_TEXT(q93 > 0.3 && q93 < 2.5, std::to_string(q93).c_str());
    CHECK_TEXT(q50 > q93, (std::to_string(q50) + " at quality 50").c_str());
}

namespace {

// The overhead camera with pixel centres on whole 0.4 mm steps of the bed: pixel (200, 150)
// sees the bed's origin.
CameraIntrinsics centred_overhead_camera() {
    CameraIntrinsics camera = overhead_camera();
    camera.cx = 200;
    camera.cy = 150;
    return camera;
}

double pixel(const GrayImage& image, int u, int v) {
    return image.pixels[static_cast<std::size_t>(v) * static_cast<std::size_t>(image.width_px) +
                        static_cast<std::size_t>(u)];
}

}  // namespace

// Over a flat grey bed (albedo 0.5) 400 mm below the lens, at 100 counts for white.
TEST_GROUP(LampAndLens) {
    const CameraIntrinsics camera = centred_overhead_camera();
    const Pose pose = look_at_pose({0, 0, 400}, {0, 0, 0}, 0);
    const StrokeScene bare_bed{{}, 0.5, 0.85, 4};
    PhotoSettings photo;
    void setup() override {
        photo.exposure_dn = 100;
    }
};

TEST(LampAndLens, the_lamps_glare_peaks_where_the_bed_mirrors_it_and_falls_off_by_hand) {
    photo.glare = {1.0, 6, {60, 0, 0}};  // the lamp 60 mm right of the lens (bed +x)
    const GrayImage image = render_photo(camera, pose, bare_bed, photo);
    // The bed mirrors the lamp half-way between the lens and the lamp: bed (30, 0), pixel 275,
    // where the half-vector is the bed's normal: 100 * (0.5 + 1.0).
    DOUBLES_EQUAL(150, pixel(image, 275, 150), 0.5);
    // Under the lens, bed (0, 0), and under the lamp, bed (60, 0): the directions to the lens and
    // the lamp are atan(60 / 400) = 8.531 deg apart, the half-vector tilts by half of it,
    // 4.265 deg, and the lobe is exp(-(4.265 / 6)^2 / 2) = 0.7767: 100 * (0.5 + 0.7767).
    DOUBLES_EQUAL(127.67, pixel(image, 200, 150), 0.5);
    DOUBLES_EQUAL(127.67, pixel(image, 350, 150), 0.5);
    // Across the lamp's line it falls off too: bed (30, 20), 50 px up.
    CHECK(pixel(image, 275, 100) < pixel(image, 275, 150));
    // A matte bed has none.
    photo.glare = glare_of_surface("matte");
    DOUBLES_EQUAL(50, pixel(render_photo(camera, pose, bare_bed, photo), 275, 150), 0.5);
    CHECK_THROWS(std::invalid_argument, glare_of_surface("velvet"));
}

TEST(LampAndLens, exposure_time_and_gain_scale_the_light_and_clip_at_255) {
    photo.exposure_time_ratio = 2;
    photo.analogue_gain = 1.5;
    DOUBLES_EQUAL(150, pixel(render_photo(camera, pose, bare_bed, photo), 10, 10), 0.5);
    photo.exposure_time_ratio = 4;
    photo.analogue_gain = 2;  // 400 counts of light: the sensor holds 255
    DOUBLES_EQUAL(255, pixel(render_photo(camera, pose, bare_bed, photo), 10, 10), 0);
    // The gain amplifies the sensor's noise with the light: 2 DN of noise at gain 3 is 6 DN.
    photo.exposure_dn = 40;
    photo.exposure_time_ratio = 1;
    photo.analogue_gain = 3;  // 60 counts, clear of both ends
    photo.noise_sigma_dn = 2;
    const auto [mean, spread] = mean_and_spread(render_photo(camera, pose, bare_bed, photo));
    DOUBLES_EQUAL(60, mean, 0.1);
    DOUBLES_EQUAL(std::sqrt(36.0 + 1.0 / 12), spread, 0.1);
    photo.analogue_gain = 0;
    CHECK_THROWS(std::invalid_argument, render_photo(camera, pose, bare_bed, photo));
}

TEST(LampAndLens, field_curvature_blurs_by_the_square_of_the_radius_as_opencvs_gaussian_does) {
    // Stripes 4 mm wide every 8 mm across the whole view: edges everywhere.
    std::vector<StrokeSegment> stripes;
    for (double x = -84; x <= 84; x += 8) stripes.push_back({{x, -70, 0}, {x, 70, 0}, 4.0});
    const StrokeScene scene(stripes, 0.1, 0.9, 4, 1.0);
    photo.exposure_dn = 200;
    photo.blur_sigma_px = 0.8;
    photo.field_curvature_px = 3;  // 3.8 px at the corners
    const GrayImage image = render_photo(camera, pose, scene, photo);
    // The reference: OpenCV's Gaussian of the sharp light at each pixel's own sigma,
    // 0.8 + 3 * rho^2 with rho = 1 at the corner pixels' centres.
    std::vector<float> light = render_albedo(camera, pose, scene);
    for (auto& a : light) a *= 200;
    const cv::Mat sharp(camera.height_px, camera.width_px, CV_32F, light.data());
    const double corner_sq = 199.5 * 199.5 + 149.5 * 149.5;
    double worst_dn = 0, steepest_centre = 0, steepest_corner = 0;
    for (const auto& [u, v] : {std::pair{200, 150},
                               {201, 150},
                               {230, 140},
                               {300, 60},
                               {120, 250},
                               {60, 40},
                               {20, 10},
                               {0, 0},
                               {399, 299},
                               {5, 290}}) {
        const double rho_sq = ((u - 199.5) * (u - 199.5) + (v - 149.5) * (v - 149.5)) / corner_sq;
        cv::Mat reference;
        cv::GaussianBlur(sharp, reference, cv::Size(0, 0), 0.8 + 3 * rho_sq, 0, cv::BORDER_REFLECT);
        worst_dn = std::max(worst_dn, std::abs(pixel(image, u, v) - reference.at<float>(v, u)));
    }
    // Rounding to counts (0.5) and the blend between layers half a pixel of sigma apart.
    CHECK_TEXT(worst_dn < 1.0, std::to_string(worst_dn).c_str());
    // And the blur does grow. A step of 160 counts (0.9 - 0.1 of 200) under a Gaussian of sigma s
    // rises at most 160 / (sqrt(2 pi) s) a pixel: near the centre (sigma 0.8, and the pixel's own
    // width) the steepest step along a row is over 45 counts; in the top-left corner's first 40
    // columns of row 3 (rho^2 above 0.8: sigma above 3.2 px) it is at most 160 / 8.0 = 20.
    for (int u = 150; u < 250; ++u)
        steepest_centre =
            std::max(steepest_centre, std::abs(pixel(image, u + 1, 150) - pixel(image, u, 150)));
    for (int u = 1; u < 40; ++u)
        steepest_corner =
            std::max(steepest_corner, std::abs(pixel(image, u + 1, 3) - pixel(image, u, 3)));
    CHECK_TEXT(steepest_centre > 45, std::to_string(steepest_centre).c_str());
    CHECK_TEXT(steepest_corner <= 21, std::to_string(steepest_corner).c_str());
}

// The photos kept between a run's tests (board/sim/photo_cache.hpp): a kept photo comes back byte
// for byte, any input changed is another photo, and a damaged file is rendered again, not read.
TEST_GROUP(KeptPhotos) {
    std::string dir;
    void setup() override {
        dir = (std::filesystem::temp_directory_path() /
               ("calbox_kept_photos_" + std::to_string(::getpid())))
                  .string();
        std::filesystem::remove_all(dir);
        ::setenv("CALBOX_TWIN_PHOTO_CACHE", dir.c_str(), 1);
    }
    void teardown() override {
        ::unsetenv("CALBOX_TWIN_PHOTO_CACHE");
        std::filesystem::remove_all(dir);
    }
};

TEST(KeptPhotos, a_kept_photo_comes_back_byte_for_byte_and_only_for_its_own_inputs) {
    CameraIntrinsics camera;
    camera.width_px = 64;
    camera.height_px = 48;
    PhotoSettings photo;
    photo.noise_sigma_dn = 2;
    const std::vector<StrokeSegment> strokes = {{{-1, 0, 0.2}, {1, 0, 0.2}, 0.4}};
    const auto key_of = [&](const PhotoSettings& p, const std::vector<StrokeSegment>& s) {
        PhotoKey key;
        key.add(camera).add(p).add(s).add("the bed");
        return key;
    };
    const GrayImage image{64, 48, std::vector<std::uint8_t>(64 * 48, 7)};
    CHECK_FALSE(kept_photo(key_of(photo, strokes)).has_value());
    keep_photo(key_of(photo, strokes), image);
    const auto back = kept_photo(key_of(photo, strokes));
    CHECK(back.has_value());
    CHECK_EQUAL(64, back->width_px);
    CHECK_EQUAL(48, back->height_px);
    CHECK(back->pixels == image.pixels);
    // Another frame's noise, another exposure, a stroke a nanometre away: not that photo.
    PhotoSettings next_frame = photo;
    next_frame.seed += 7919;
    CHECK_FALSE(kept_photo(key_of(next_frame, strokes)).has_value());
    PhotoSettings shorter = photo;
    shorter.exposure_time_ratio = 0.5;
    CHECK_FALSE(kept_photo(key_of(shorter, strokes)).has_value());
    auto moved = strokes;
    moved[0].b_mm.x += 1e-6;
    CHECK_FALSE(kept_photo(key_of(photo, moved)).has_value());
    // Cut short (a test killed while another read it): treated as not kept.
    const auto path = std::filesystem::path(dir) / (key_of(photo, strokes).digest() + ".gray");
    std::filesystem::resize_file(path, std::filesystem::file_size(path) - 1);
    CHECK_FALSE(kept_photo(key_of(photo, strokes)).has_value());
}

TEST(KeptPhotos, without_the_directory_nothing_is_kept) {
    ::unsetenv("CALBOX_TWIN_PHOTO_CACHE");
    PhotoKey key;
    key.add("anything");
    keep_photo(key, GrayImage{2, 2, {1, 2, 3, 4}});
    CHECK_FALSE(kept_photo(key).has_value());
    CHECK_FALSE(std::filesystem::exists(dir));
}
