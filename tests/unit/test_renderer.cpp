// The photo renderer and the twin's camera, judged against OpenCV and hand-worked values.
#include <CppUTest/TestHarness.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "board/sim/camera_reference.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/photo_cache.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/scenes.hpp"

using namespace calbox;
using namespace calbox::sim;

namespace {

CameraIntrinsics pinhole_1080p() {
    CameraIntrinsics c;
    c.model = LensModel::pinhole;
    c.width_px = 1920;
    c.height_px = 1080;
    c.fx = 1500;
    c.fy = 1502;
    c.cx = 962.3;
    c.cy = 537.8;
    c.distortion = {-0.12, 0.08, 0.0007, -0.0005, -0.01};
    return c;
}

CameraIntrinsics fisheye_1080p() {
    CameraIntrinsics c = pinhole_1080p();
    c.model = LensModel::fisheye;
    c.fx = c.fy = 1100;
    c.distortion = {-0.03, 0.01, -0.004, 0.0008};
    return c;
}

cv::Mat camera_matrix(const CameraIntrinsics& c) {
    return (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
}

// The board centred in front of the camera at 400 mm, tilted `tilt_deg` about its x axis.
Pose board_pose(double centre_x_mm, double centre_y_mm, double tilt_deg, double distance_mm) {
    Pose p;
    p.rotation = rotation_from_vector({radians(tilt_deg), 0, 0});
    const Vec3 centre = p.rotation * Vec3{centre_x_mm, centre_y_mm, 0};
    p.translation_mm = Vec3{0, 0, distance_mm} - centre;
    return p;
}

std::vector<cv::Point2d> opencv_projection(const CameraIntrinsics& c, const Pose& pose,
                                           const std::vector<cv::Point3d>& points) {
    const Vec3 r = vector_from_rotation(pose.rotation);
    const cv::Vec3d rvec(r.x, r.y, r.z);
    const cv::Vec3d tvec(pose.translation_mm.x, pose.translation_mm.y, pose.translation_mm.z);
    std::vector<cv::Point2d> out;
    if (c.model == LensModel::fisheye) {
        cv::fisheye::projectPoints(points, out, rvec, tvec, camera_matrix(c), c.distortion);
    } else {
        cv::projectPoints(points, rvec, tvec, camera_matrix(c), c.distortion, out);
    }
    return out;
}

cv::Mat as_mat(const GrayImage& image) {
    return cv::Mat(image.height_px, image.width_px, CV_8UC1,
                   const_cast<std::uint8_t*>(image.pixels.data()))
        .clone();
}

// RMS distance from each detected corner to the nearest OpenCV projection of a board corner.
double rms_to_nearest(const std::vector<cv::Point2f>& found,
                      const std::vector<cv::Point2d>& truth) {
    double sum = 0;
    for (const auto& f : found) {
        double best = 1e300;
        for (const auto& t : truth) best = std::min(best, std::hypot(f.x - t.x, f.y - t.y));
        sum += best * best;
    }
    return std::sqrt(sum / found.size());
}

double chessboard_corner_rms(const CameraIntrinsics& camera) {
    const auto spec = geometry::parse_pattern_spec("chessboard:9x6@20");
    const Pose pose = board_pose(80, 50, 10, 400);
    const BoardScene scene(spec, 4);
    // OpenCV's saddle refinement is biased by up to 0.07 px on perfectly sharp X-junctions
    // (the rendered edges themselves are exact to 0.002 px); a defocused lens, as on the box,
    // and a wide window take that away, so what is left measures the renderer.
    PhotoSettings photo;
    photo.blur_sigma_px = 2.0;
    const GrayImage image = render_photo(camera, pose, scene, photo);
    const cv::Mat gray = as_mat(image);
    std::vector<cv::Point2f> corners;
    CHECK_TRUE(cv::findChessboardCorners(gray, cv::Size(9, 6), corners));
    cv::cornerSubPix(gray, corners, cv::Size(15, 15), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
    std::vector<cv::Point3d> object;
    for (const auto& f : scene.features()) object.emplace_back(f.position_mm.x, f.position_mm.y, 0);
    CHECK_EQUAL(54u, corners.size());
    return rms_to_nearest(corners, opencv_projection(camera, pose, object));
}

}  // namespace

TEST_GROUP(Coverage){};

TEST(Coverage, half_plane_fractions_worked_by_hand) {
    const double unit[2][2] = {{1, 0}, {0, 1}};
    DOUBLES_EQUAL(0.5, inside_fraction(0, {1, 0}, unit, 1), 1e-12);
    DOUBLES_EQUAL(0.75, inside_fraction(-0.25, {1, 0}, unit, 1), 1e-12);
    DOUBLES_EQUAL(1.0, inside_fraction(-0.6, {1, 0}, unit, 1), 1e-12);
    const double s = 1 / std::sqrt(2.0);
    DOUBLES_EQUAL(0.5, inside_fraction(0, {s, s}, unit, 1), 1e-12);
    // Edge u + v = -1/2 cuts a corner triangle with legs 1/2: area 1/8.
    DOUBLES_EQUAL(0.125, inside_fraction(0.5 * s, {s, s}, unit, 1), 1e-12);
    DOUBLES_EQUAL(0.875, inside_fraction(-0.5 * s, {s, s}, unit, 1), 1e-12);
    // A pixel 0.1 mm wide split into 4 sub-squares: an edge 0.0125 mm from a sub-square's centre.
    const double small[2][2] = {{0.1, 0}, {0, 0.1}};
    DOUBLES_EQUAL(1.0, inside_fraction(-0.0125, {0, 1}, small, 4), 1e-12);
    DOUBLES_EQUAL(0.75, inside_fraction(-0.00625, {0, 1}, small, 4), 1e-12);
}

TEST_GROUP(TwinCamera){};

TEST(TwinCamera, projection_agrees_with_opencv_pinhole_and_fisheye) {
    const Pose pose = board_pose(80, 50, 10, 400);
    std::vector<cv::Point3d> points;
    for (double x = -100; x <= 260; x += 20)
        for (double y = -80; y <= 180; y += 20) points.emplace_back(x, y, (x + y) * 0.01);
    for (const auto& camera : {pinhole_1080p(), fisheye_1080p()}) {
        const auto cv_px = opencv_projection(camera, pose, points);
        for (std::size_t i = 0; i < points.size(); ++i) {
            const Vec2 px = project_point(camera, pose, {points[i].x, points[i].y, points[i].z});
            DOUBLES_EQUAL(cv_px[i].x, px.x, 1e-6);
            DOUBLES_EQUAL(cv_px[i].y, px.y, 1e-6);
        }
    }
}

TEST(TwinCamera, undistortion_inverts_distortion) {
    for (const auto& camera : {pinhole_1080p(), fisheye_1080p()}) {
        for (double u = 0; u <= 1920; u += 160) {
            for (double v = 0; v <= 1080; v += 120) {
                const Vec2 n = undistort_pixel(camera, u, v);
                const Vec2 back = distort_normalized(camera, n.x, n.y);
                DOUBLES_EQUAL(u, back.x, 1e-8);
                DOUBLES_EQUAL(v, back.y, 1e-8);
            }
        }
    }
}

TEST(TwinCamera, look_at_pose_sees_the_bed_unmirrored) {
    // From above, bed +x is image right and bed +y is image up.
    const Pose pose = look_at_pose({0, 0, 400}, {0, 0, 0}, 0);
    const CameraIntrinsics c = pinhole_1080p();
    const Vec2 origin = project_point(c, pose, {0, 0, 0});
    const Vec2 x = project_point(c, pose, {10, 0, 0});
    const Vec2 y = project_point(c, pose, {0, 10, 0});
    CHECK(x.x > origin.x + 30);
    CHECK(y.y < origin.y - 30);
}

TEST_GROUP(BoardRender){};

TEST(BoardRender, chessboard_corners_agree_with_projectpoints_pinhole_tilted_10_degrees) {
    const double rms = chessboard_corner_rms(pinhole_1080p());
    CHECK_TEXT(rms < 0.02, ("pinhole corner RMS " + std::to_string(rms) + " px").c_str());
}

// The rays of the last lens are kept between photos: a lens that differs only in its distortion,
// or only by a thousandth of a pixel in its centre, is traced afresh (its corners land where OpenCV
// puts them, not where the kept lens would), and the kept lens's photo, made again after it, is bit
// for bit the first.
TEST(BoardRender, a_photo_is_traced_through_its_own_lens_whatever_lens_came_before) {
    const auto spec = geometry::parse_pattern_spec("chessboard:9x6@20");
    const BoardScene scene(spec, 4);
    const Pose pose = board_pose(80, 50, 10, 400);
    const CameraIntrinsics kept = pinhole_1080p();
    const auto first = render_albedo(kept, pose, scene);
    CameraIntrinsics other = kept;
    other.distortion = {0.05, -0.02, 0, 0, 0};  // corners several pixels from the kept lens's
    const double rms = chessboard_corner_rms(other);
    CHECK_TEXT(rms < 0.02, ("another lens's corner RMS " + std::to_string(rms) + " px").c_str());
    CameraIntrinsics shifted = kept;
    shifted.cx += 0.001;
    CHECK(render_albedo(shifted, pose, scene) != first);
    CHECK(render_albedo(kept, pose, scene) == first);
}

TEST(BoardRender, chessboard_corners_agree_with_projectpoints_fisheye_tilted_10_degrees) {
    const double rms = chessboard_corner_rms(fisheye_1080p());
    CHECK_TEXT(rms < 0.02, ("fisheye corner RMS " + std::to_string(rms) + " px").c_str());
}

TEST(BoardRender, charuco_markers_decode_with_their_ids_at_their_true_corners) {
    const auto spec = geometry::parse_pattern_spec("charuco:5x7@20/14:DICT_6X6_250");
    const Pose pose = board_pose(50, 70, 8, 400);
    const BoardScene scene(spec, 4);
    PhotoSettings photo;
    photo.blur_sigma_px = 0.6;
    const cv::Mat gray = as_mat(render_photo(pinhole_1080p(), pose, scene, photo));
    const auto dictionary = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250);
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    const auto parameters = cv::aruco::DetectorParameters::create();
    parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    cv::aruco::detectMarkers(gray, dictionary, corners, ids, parameters);
    CHECK_EQUAL(17u, ids.size());  // 5 x 7 squares hold 17 markers
    std::vector<cv::Point3d> object;
    std::vector<std::pair<int, int>> which;
    for (const auto& f : scene.features()) {
        if (f.corner < 0) continue;
        object.emplace_back(f.position_mm.x, f.position_mm.y, 0);
        which.emplace_back(f.id, f.corner);
    }
    const auto truth = opencv_projection(pinhole_1080p(), pose, object);
    double worst = 0;
    for (std::size_t m = 0; m < ids.size(); ++m) {
        for (int k = 0; k < 4; ++k) {
            bool matched = false;
            for (std::size_t t = 0; t < which.size(); ++t) {
                if (which[t] != std::make_pair(ids[m], k)) continue;
                worst = std::max(
                    worst, std::hypot(corners[m][k].x - truth[t].x, corners[m][k].y - truth[t].y));
                matched = true;
            }
            CHECK(matched);
        }
    }
    // OpenCV's sub-pixel refinement is biased a few tenths of a pixel towards a marker's
    // centre; a mirrored, rotated or misplaced marker would be off by its whole size.
    CHECK_TEXT(worst < 0.5, ("worst marker corner " + std::to_string(worst) + " px").c_str());
}

TEST_GROUP(PrintPhoto){};

namespace {

struct SquareMeasure {
    double left, right, bottom, top;  // stroke centrelines in bed mm
};

// Measures the square outline's four sides in the photo, as a test instrument: samples lines
// across each stroke on the bed (at the strokes' top height), projects them with the true
// camera, and takes the centroid of the material signal along each line.
SquareMeasure measure_square(const cv::Mat& gray, const CameraIntrinsics& camera, const Pose& pose,
                             double half_side_mm, double top_z_mm, double along_from,
                             double along_to) {
    cv::Mat image;
    gray.convertTo(image, CV_32F);
    const auto sample = [&](double x, double y) {
        const Vec2 px = project_point(camera, pose, {x, y, top_z_mm});
        cv::Mat patch;
        cv::getRectSubPix(image, cv::Size(1, 1),
                          cv::Point2f(static_cast<float>(px.x), static_cast<float>(px.y)), patch);
        return static_cast<double>(patch.at<float>(0, 0));
    };
    const auto centreline = [&](double nominal, bool across_x) {
        double sum_position = 0;
        int count = 0;
        for (double along = along_from; along <= along_to + 1e-9; along += 0.1) {
            std::vector<double> offsets, values;
            for (double d = -1.6; d <= 1.6 + 1e-9; d += 0.005) {
                const double across = nominal + d;
                offsets.push_back(across);
                values.push_back(across_x ? sample(across, along) : sample(along, across));
            }
            double background = 0;
            int n = 0;
            for (std::size_t i = 0; i < values.size(); ++i) {
                if (std::abs(offsets[i] - nominal) > 1.0) {
                    background += values[i];
                    ++n;
                }
            }
            background /= n;
            double w = 0, wx = 0;
            for (std::size_t i = 0; i < values.size(); ++i) {
                w += values[i] - background;
                wx += (values[i] - background) * offsets[i];
            }
            sum_position += wx / w;
            ++count;
        }
        return sum_position / count;
    };
    return {centreline(-half_side_mm, true), centreline(half_side_mm, true),
            centreline(-half_side_mm, false), centreline(half_side_mm, false)};
}

struct PrintedSquare {
    cv::Mat photo;
    CameraIntrinsics camera;
    Pose pose;
};

PrintedSquare print_and_photograph(const DeltaParams& truth, const DeltaParams& firmware) {
    DeltaTwin twin(truth, firmware);
    twin.zero_height_at_centre();
    GcodeRunner runner(twin, ToolSettings{});
    std::istringstream job(
        "G28\nG92 E0\nG0 Z5\nG0 X-20 Y-20\nG0 Z0.2\n"
        "G1 X20 Y-20 E1.8\nG1 X20 Y20 E3.6\nG1 X-20 Y20 E5.4\nG1 X-20 Y-20 E7.2\n");
    runner.run(job);
    std::vector<StrokeSegment> strokes;
    for (const auto& s : runner.result().strokes) strokes.push_back(sim::material_of(s));
    PrintedSquare out;
    out.camera.width_px = 1300;
    out.camera.height_px = 1100;
    out.camera.fx = out.camera.fy = 5700;  // 0.07 mm/px at 400 mm
    out.camera.cx = 651.2;
    out.camera.cy = 548.7;
    out.camera.distortion = {-0.05, 0.08, 0, 0, 0};
    // Tilted about 5 degrees: the camera sits 35 mm off the axis, looking at the bed centre.
    out.pose = look_at_pose({0, -35, 400}, {0, 0, 0}, 0);
    PhotoSettings photo;
    photo.blur_sigma_px = 0.7;
    const StrokeScene scene(std::move(strokes), 0.08, 0.85, 4);
    out.photo = as_mat(render_photo(out.camera, out.pose, scene, photo));
    return out;
}

}  // namespace

TEST(PrintPhoto, square_printed_by_an_exact_delta_measures_true_in_the_photo) {
    const DeltaParams exact{};
    const auto square = print_and_photograph(exact, exact);
    const auto m = measure_square(square.photo, square.camera, square.pose, 20, 0.2, -15, 15);
    DOUBLES_EQUAL(40.0, m.right - m.left, 0.005);
    DOUBLES_EQUAL(40.0, m.top - m.bottom, 0.005);
    DOUBLES_EQUAL(0.0, (m.right + m.left) / 2, 0.005);
    DOUBLES_EQUAL(0.0, (m.top + m.bottom) / 2, 0.005);
}

TEST(PrintPhoto, longer_rods_grow_the_square_by_the_hand_worked_amount) {
    DeltaParams truth{};
    truth.diagonal_rod_mm = 251;
    const auto square = print_and_photograph(truth, DeltaParams{});
    // Mid-side true positions from tests/reference/delta_hand.py, at the stroke top z ~ 0.2044.
    const auto m =
        measure_square(square.photo, square.camera, square.pose, 20.1168, 0.2044, -1.5, 1.5);
    DOUBLES_EQUAL(20.116758375, m.right, 0.005);
    DOUBLES_EQUAL(-20.116758375, m.left, 0.005);
    DOUBLES_EQUAL(20.114839225, m.top, 0.005);
    DOUBLES_EQUAL(-20.118677554, m.bottom, 0.005);
    DOUBLES_EQUAL(40.233516750, m.right - m.left, 0.005);
}

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

namespace {

// A photo's mean and standard deviation, in counts.
std::pair<double, double> mean_and_spread(const GrayImage& image) {
    double sum = 0, sum2 = 0;
    for (const auto p : image.pixels) {
        sum += p;
        sum2 += static_cast<double>(p) * p;
    }
    const double n = static_cast<double>(image.pixels.size());
    return {sum / n, std::sqrt(sum2 / n - (sum / n) * (sum / n))};
}

}  // namespace

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

namespace {

CameraIntrinsics overhead_camera() {
    CameraIntrinsics camera;
    camera.width_px = 400;
    camera.height_px = 300;
    camera.fx = camera.fy = 1000;  // 0.4 mm a pixel at 400 mm
    camera.cx = 199.5;
    camera.cy = 149.5;
    return camera;
}

// Where along a row the highlight's excess over the plain material is centred, in bed mm
// (0.4 mm a pixel, the camera over the origin), and how high it peaks.
std::pair<double, double> highlight_across_row(const std::vector<float>& albedo, int row,
                                               double material) {
    double sum = 0, weighted = 0, peak = 0;
    for (int u = 0; u < 400; ++u) {
        const double excess = albedo[static_cast<std::size_t>(row) * 400 + u] - material;
        if (excess <= 0.01) continue;
        sum += excess;
        weighted += excess * u;
        peak = std::max(peak, excess);
    }
    if (sum == 0) return {0.0, 0.0};
    return {(weighted / sum - 199.5) * 0.4, peak};
}

}  // namespace

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
