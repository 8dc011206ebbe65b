// The photo renderer and the twin's camera, judged against OpenCV and hand-worked values.
#include "tests/unit/renderer_checks.hpp"

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
