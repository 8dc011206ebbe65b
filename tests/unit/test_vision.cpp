// core/vision judged on twin-rendered images, against the twin's truth.
#include <CppUTest/TestHarness.h>
#include <apriltag/apriltag.h>
#include <apriltag/tagStandard41h12.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <random>

#include "board/sim/camera_reference.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/scenes.hpp"
#include "board/sim/sim_board.hpp"
#include "core/geometry/calibration.hpp"
#include "core/modes/mark_grid.hpp"
#include "core/number_text.hpp"
#include "core/vision/edge_kernel.hpp"
#include "core/vision/exposure.hpp"
#include "core/vision/markers.hpp"
#include "core/vision/reference_marks.hpp"
#include "core/vision/spots.hpp"
#include "core/vision/strand_ring.hpp"
#include "tests/support/surroundings.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;
using test::as_core;
using test::hq_camera;
using test::view_of;

namespace {

struct MarkerScene {
    sim::GrayImage image;
    std::map<std::pair<int, int>, sim::Vec2> truth;  // (id, corner) -> pixel
};

MarkerScene photograph_markers(double angle_deg, const std::string& dictionary = "DICT_4X4_50") {
    const auto camera = hq_camera();
    const sim::Pose board = sim::compose(sim::look_at_pose({0, -35, 400}, {0, 0, 0}, 0),
                                         sim::board_lying_on_bed({-70, 45, 0}, angle_deg));
    const sim::BoardScene scene(geometry::parse_pattern_spec("aruco:4x3@30/8:" + dictionary), 4);
    sim::PhotoSettings photo;
    photo.noise_sigma_dn = 2.0;
    photo.blur_sigma_px = 0.7;
    photo.vignetting = 0.15;
    photo.lighting_gradient = 0.1;
    MarkerScene out{sim::render_photo(camera, board, scene, photo), {}};
    for (const auto& f : scene.features())
        out.truth[{f.id, f.corner}] = sim::project_point(camera, board, f.position_mm);
    return out;
}

double corner_rms(const MarkerScene& scene, const std::vector<vision::DetectedMarker>& found) {
    double sum = 0;
    int n = 0;
    for (const auto& m : found) {
        for (int k = 0; k < 4; ++k) {
            const auto t = scene.truth.at({m.id, k});
            sum += std::pow(m.corners[static_cast<std::size_t>(k)].x - t.x, 2) +
                   std::pow(m.corners[static_cast<std::size_t>(k)].y - t.y, 2);
            ++n;
        }
    }
    return std::sqrt(sum / n);
}

}  // namespace

TEST_GROUP(EdgeKernel){};

TEST(EdgeKernel, fixed_point_agrees_with_double_reference_to_a_hundredth_of_a_pixel) {
    const auto scene = photograph_markers(17);
    const auto view = view_of(scene.image);
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> x(100, 3900), y(100, 2900), angle(0, 2 * sim::kPi);
    double worst_sample = 0, worst_edge = 0;
    int edges = 0;
    for (int trial = 0; trial < 3000; ++trial) {
        const double x0 = x(rng), y0 = y(rng), a = angle(rng), step = 0.125;
        const double dx = std::cos(a) * step, dy = std::sin(a) * step;
        constexpr int kCount = 49;
        std::int32_t fixed[kCount];
        CHECK(vision::sample_profile_q8(view, vision::to_q16(x0), vision::to_q16(y0),
                                        vision::to_q16(dx), vision::to_q16(dy), kCount, fixed));
        std::vector<double> reference;
        for (int i = 0; i < kCount; ++i) {
            reference.push_back(vision::sample_reference(view, x0 + i * dx, y0 + i * dy));
            worst_sample = std::max(worst_sample, std::abs(fixed[i] / 256.0 - reference.back()));
        }
        for (const bool rising : {true, false}) {
            const auto f = vision::step_edge_q16(fixed, kCount, rising);
            const auto r = vision::step_edge_reference(reference, rising);
            CHECK(f.has_value() == r.has_value());
            if (!f || !r) continue;
            // Only profiles that cross a real edge of this polarity matter; elsewhere the
            // "edge" is noise either way.
            const double rise = reference.back() - reference.front();
            if ((rising ? rise : -rise) < 60) continue;
            worst_edge = std::max(worst_edge, std::abs(vision::from_q16(*f) - *r) * step);
            ++edges;
        }
    }
    CHECK(edges > 50);
    CHECK_TEXT(worst_sample < 0.05,
               ("worst sample " + std::to_string(worst_sample) + " DN").c_str());
    CHECK_TEXT(worst_edge < 0.01, ("worst edge " + std::to_string(worst_edge) + " px").c_str());
}

TEST(EdgeKernel, refuses_profiles_leaving_the_image) {
    const std::vector<std::uint8_t> pixels(16 * 16, 50);
    const vision::GrayView view{pixels.data(), 16, 16, 16};
    std::int32_t out[8];
    CHECK_FALSE(vision::sample_profile_q8(view, vision::to_q16(14.5), vision::to_q16(3),
                                          vision::to_q16(0.5), 0, 8, out));
    CHECK_FALSE(vision::sample_profile_q8(view, vision::to_q16(-0.5), vision::to_q16(3),
                                          vision::to_q16(0.5), 0, 2, out));
    CHECK(vision::sample_profile_q8(view, vision::to_q16(1), vision::to_q16(3), vision::to_q16(0.5),
                                    0, 8, out));
    CHECK_EQUAL(50 * 256, out[3]);
    CHECK_FALSE(vision::step_edge_q16(out, 8, true).has_value());  // flat: no edge
}

TEST_GROUP(Markers){};

TEST(Markers, every_rendered_marker_is_found_with_corners_within_a_tenth_of_a_pixel) {
    const auto scene = photograph_markers(17);
    vision::MarkerOptions options;
    options.dictionary = "DICT_4X4_50";
    const auto found = vision::detect_markers(view_of(scene.image), options);
    CHECK_EQUAL(12u, found.size());
    for (std::size_t i = 0; i < found.size(); ++i) CHECK_EQUAL(static_cast<int>(i), found[i].id);
    const double rms = corner_rms(scene, found);
    CHECK_TEXT(rms < 0.1, ("marker corner RMS " + std::to_string(rms) + " px").c_str());
    // Each corner carries its edge fits' uncertainty: well under the 0.2 px OpenCV's own
    // corners are worth, and not zero.
    for (const auto& m : found) {
        for (const double s : m.sigma_px)
            CHECK_TEXT(s > 1e-4 && s < 0.05, std::to_string(s).c_str());
    }

    // With the camera the edges are fitted as the straight lines they are on the marker.
    const auto camera = as_core(hq_camera());
    options.camera = &camera;
    const double with_camera =
        corner_rms(scene, vision::detect_markers(view_of(scene.image), options));
    CHECK_TEXT(with_camera < 0.03,
               ("marker corner RMS with camera " + std::to_string(with_camera) + " px").c_str());

    // OpenCV's own sub-pixel corners, for comparison: the refinement must beat them.
    options.refine_edges = false;
    options.camera = nullptr;
    const double opencv = corner_rms(scene, vision::detect_markers(view_of(scene.image), options));
    UT_PRINT(("marker corners RMS: edge fit " + std::to_string(rms) + " px, with camera " +
              std::to_string(with_camera) + " px, OpenCV's subpixel " + std::to_string(opencv) +
              " px")
                 .c_str());
    CHECK_TEXT(opencv > 2 * with_camera,
               ("OpenCV corner RMS " + std::to_string(opencv) + " px").c_str());
}

TEST(Markers, a_corner_that_cannot_be_refined_is_kept_as_found_and_says_why) {
    const auto scene = photograph_markers(17);
    vision::MarkerOptions options;
    const auto found = vision::detect_markers(view_of(scene.image), options);
    for (const auto& m : found) {
        CHECK_TEXT(m.refined, m.unrefined_because.c_str());
        CHECK_TRUE(m.unrefined_because.empty());
    }
    // OpenCV's corners two and a half pixels to the right: the side edges are still within the
    // profiles' reach and the refinement lands on the true corners, further from the rough ones
    // than a refinement may move.
    const auto& marker = found.at(3);
    std::array<geometry::Point2, 4> rough = marker.corners;
    for (auto& c : rough) c.x += 2.5;
    const auto shifted = vision::refine_marker_corners(view_of(scene.image), rough, 6, nullptr);
    CHECK_FALSE(shifted.refined);
    DOUBLES_EQUAL(0.2, shifted.sigma_px[2], 0);
    STRCMP_CONTAINS("px from OpenCV's (at most 2.0)", shifted.unrefined_because.c_str());
    for (std::size_t k = 0; k < 4; ++k) DOUBLES_EQUAL(rough[k].x, shifted.corners[k].x, 0);
    // The same with the limit raised: refined, onto the truth.
    vision::MarkerRefineLimits wide;
    wide.max_corner_move_px = 4;
    const auto allowed =
        vision::refine_marker_corners(view_of(scene.image), rough, 6, nullptr, wide);
    CHECK_TRUE(allowed.refined);
    for (int k = 0; k < 4; ++k) {
        const auto t = scene.truth.at({marker.id, k});
        const auto& c = allowed.corners[static_cast<std::size_t>(k)];
        CHECK_TEXT(std::hypot(c.x - t.x, c.y - t.y) < 0.2, ("corner " + std::to_string(k)).c_str());
    }
    // A blank patch has no edges.
    const std::vector<std::uint8_t> flat(64 * 64, 120);
    const auto blank = vision::refine_marker_corners(
        {flat.data(), 64, 64, 64}, {{{10, 10}, {50, 10}, {50, 50}, {10, 50}}}, 6, nullptr);
    CHECK_FALSE(blank.refined);
    STRCMP_EQUAL("the top edge gave 0 points (at least 6 needed)", blank.unrefined_because.c_str());
    // Refinement off: every marker says so.
    options.refine_edges = false;
    for (const auto& m : vision::detect_markers(view_of(scene.image), options)) {
        CHECK_FALSE(m.refined);
        STRCMP_EQUAL("refinement off", m.unrefined_because.c_str());
    }
}

// AprilTag families through libapriltag: the same codes OpenCV knows as DICT_APRILTAG_36h11 and
// 25h9, found by AprilTag's own detector, give the same ids and OpenCV's corner order.
TEST(Markers, apriltag_families_are_found_by_libapriltag_in_opencvs_corner_order) {
    for (const auto& [opencv_name, family] :
         {std::pair<std::string, std::string>{"DICT_APRILTAG_36h11", "tag36h11"},
          {"DICT_APRILTAG_25h9", "tag25h9"}}) {
        const auto scene = photograph_markers(17, opencv_name);
        vision::MarkerOptions options;
        options.dictionary = family;
        const auto found = vision::detect_markers(view_of(scene.image), options);
        CHECK_EQUAL_TEXT(12u, found.size(), family.c_str());
        for (std::size_t i = 0; i < found.size(); ++i) {
            CHECK_EQUAL(static_cast<int>(i), found[i].id);
            CHECK_TEXT(found[i].refined, found[i].unrefined_because.c_str());
        }
        const double rms = corner_rms(scene, found);
        UT_PRINT((family + ": corner RMS " + std::to_string(rms) + " px").c_str());
        CHECK_TEXT(rms < 0.1, (family + " corner RMS " + std::to_string(rms) + " px").c_str());
    }
}

// tagStandard41h12 has no OpenCV dictionary: its tags are drawn from libapriltag's own layout,
// cell by cell, at 12 px a cell under a perspective, each pixel the mean of 4x4 samples. Its
// found outline is white inside a black ring, the other way round from ArUco's.
TEST(Markers, apriltag_standard_41h12_tags_are_found_with_refined_corners) {
    const int width = 1400, height = 1000, ss = 4;
    // Cell coordinates (x, y in cells of the tag image, top-left origin) of tag `i` to pixels.
    const auto homography = [](int i) {
        const double ox = 150 + 420.0 * (i % 3), oy = 170 + 430.0 * (i / 3), a = 0.3 + 0.2 * i;
        cv::Matx33d h(12.3 * std::cos(a), -12.3 * std::sin(a), ox, 12.1 * std::sin(a),
                      12.1 * std::cos(a), oy, 0.0004 * i, -0.0003, 1);
        return h;
    };
    const auto map = [](const cv::Matx33d& h, double x, double y) {
        const cv::Vec3d p = h * cv::Vec3d(x, y, 1);
        return sim::Vec2{p[0] / p[2], p[1] / p[2]};
    };
    const std::unique_ptr<apriltag_family_t, void (*)(apriltag_family_t*)> family(
        tagStandard41h12_create(), tagStandard41h12_destroy);
    const int ids[] = {0, 5, 17, 200, 999, 2114};
    std::vector<cv::Mat> tags;
    for (const int id : ids) {
        image_u8_t* t = apriltag_to_image(family.get(), id);
        tags.push_back(cv::Mat(t->height, t->width, CV_8U, t->buf, t->stride).clone());
        image_u8_destroy(t);
    }
    cv::Mat sharp(height * ss, width * ss, CV_8U, cv::Scalar(216));
    for (int i = 0; i < 6; ++i) {
        const cv::Matx33d to_cells = homography(i).inv();
        const int n = tags[static_cast<std::size_t>(i)].cols;
        for (int y = 0; y < sharp.rows; ++y) {
            for (int x = 0; x < sharp.cols; ++x) {
                const auto c = map(to_cells, (x + 0.5) / ss - 0.5, (y + 0.5) / ss - 0.5);
                const int cx = static_cast<int>(std::floor(c.x)),
                          cy = static_cast<int>(std::floor(c.y));
                if (cx < 0 || cy < 0 || cx >= n || cy >= n) continue;
                sharp.at<std::uint8_t>(y, x) =
                    tags[static_cast<std::size_t>(i)].at<std::uint8_t>(cy, cx) > 127 ? 216 : 12;
            }
        }
    }
    cv::Mat photo;
    cv::resize(sharp, photo, cv::Size(width, height), 0, 0, cv::INTER_AREA);
    cv::GaussianBlur(photo, photo, cv::Size(0, 0), 0.7);
    cv::Mat noise(photo.size(), CV_16S);
    cv::randn(noise, 0, 2);
    photo.convertTo(photo, CV_16S);
    photo += noise;
    photo.convertTo(photo, CV_8U);
    vision::MarkerOptions options;
    options.dictionary = "tagStandard41h12";
    const auto found = vision::detect_markers(
        {photo.data, photo.cols, photo.rows, static_cast<int>(photo.step)}, options);
    CHECK_EQUAL(6u, found.size());
    // The outline found is the border square, width_at_border cells wide, centred in the tag.
    const double start = (family->total_width - family->width_at_border) / 2.0;
    const double end = start + family->width_at_border;
    double sum = 0;
    int n = 0;
    for (const auto& m : found) {
        const auto at = std::find(std::begin(ids), std::end(ids), m.id);
        CHECK(at != std::end(ids));
        CHECK_TEXT(m.refined, m.unrefined_because.c_str());
        const auto h = homography(static_cast<int>(at - std::begin(ids)));
        const sim::Vec2 truth[4] = {map(h, start, start), map(h, end, start), map(h, end, end),
                                    map(h, start, end)};
        for (std::size_t k = 0; k < 4; ++k) {
            sum +=
                std::pow(m.corners[k].x - truth[k].x, 2) + std::pow(m.corners[k].y - truth[k].y, 2);
            ++n;
        }
    }
    const double rms = std::sqrt(sum / std::max(1, n));
    UT_PRINT(("tagStandard41h12: corner RMS " + std::to_string(rms) + " px").c_str());
    CHECK_TEXT(rms < 0.1, ("corner RMS " + std::to_string(rms) + " px").c_str());
}

TEST(Markers, unknown_dictionary_is_refused) {
    const std::vector<std::uint8_t> pixels(64 * 64, 50);
    vision::MarkerOptions options;
    options.dictionary = "DICT_3X3_7";
    try {
        vision::detect_markers({pixels.data(), 64, 64, 64}, options);
        FAIL("an unknown dictionary was accepted");
    } catch (const geometry::PatternError& e) {
        STRCMP_CONTAINS("unknown marker dictionary 'DICT_3X3_7'", e.what());
        STRCMP_CONTAINS("tagStandard41h12", e.what());
    }
}

TEST_GROUP(DotGrids){};

TEST(DotGrids, symmetric_and_asymmetric_grids_are_found_at_their_true_centres) {
    const auto camera = hq_camera();
    const auto bed = sim::look_at_pose({0, -35, 400}, {0, 0, 0}, 0);
    for (const char* text : {"circles:7x5@15", "acircles:4x11@10"}) {
        const auto spec = geometry::parse_pattern_spec(text);
        const sim::Pose board = sim::compose(bed, sim::board_lying_on_bed({-50, 45, 0}, 8));
        const sim::BoardScene scene(spec, 4);
        sim::PhotoSettings photo;
        photo.noise_sigma_dn = 2.0;
        photo.blur_sigma_px = 0.7;
        const auto image = sim::render_photo(camera, board, scene, photo);
        const auto found = geometry::find_board(spec, view_of(image));
        CHECK_TEXT(found.has_value(), text);
        const auto features = scene.features();
        CHECK_EQUAL(features.size(), found->image_points.size());
        double worst = 0;
        for (std::size_t i = 0; i < features.size(); ++i) {
            // Same order and board positions as the twin's dots.
            DOUBLES_EQUAL(features[i].position_mm.x, found->object_points[i].x, 1e-9);
            DOUBLES_EQUAL(features[i].position_mm.y, found->object_points[i].y, 1e-9);
            const auto truth = sim::project_point(camera, board, features[i].position_mm);
            worst = std::max(worst, std::hypot(found->image_points[i].x - truth.x,
                                               found->image_points[i].y - truth.y));
        }
        // Blob centroids of dots seen in perspective sit a little off the true centres.
        CHECK_TEXT(worst < 0.3,
                   (std::string(text) + " worst centre " + std::to_string(worst) + " px").c_str());
    }
}

TEST_GROUP(ReferenceMarks){};

namespace {

// Where a knocked camera makes a bed point seem to be: the pixel it lands on now, traced back
// through the camera as it was (the stored plane), onto the bed. The twin's own camera model.
sim::Vec2 apparent_on_bed(const sim::CameraIntrinsics& c, const sim::Pose& before,
                          const sim::Pose& after, const sim::Vec3& p) {
    const sim::Vec2 px = sim::project_point(c, after, p);
    const sim::Vec2 n = sim::undistort_pixel(c, px.x, px.y);
    const sim::Vec3 centre = before.camera_centre_in_plane();
    const sim::Vec3 ray = before.rotation.transposed() * sim::Vec3{n.x, n.y, 1};
    const double t = -centre.z / ray.z;
    return {centre.x + t * ray.x, centre.y + t * ray.y};
}

}  // namespace

// The marks' view is taken with the plane (the board on the bed); after a knock that turns the
// camera, the marks seem to move on the bed by what the twin's geometry says; unknocked, they
// stay within the noise of two photos.
TEST(ReferenceMarks, a_knocked_camera_moves_the_marks_by_what_the_twins_geometry_says) {
    const auto scenario = sim::load_scenario(std::string(CALBOX_SOURCE_DIR) +
                                             "/tests/scenarios/delta_cycle_small.toml");
    sim::TwinBench bench(scenario);
    const auto& c = scenario.camera->intrinsics;
    const auto camera = sim::as_camera_model(c);
    bench.lay_plane_board_on_bed();
    const auto plane_photo = bench.photograph(0);
    const auto plane = geometry::estimate_bed_plane(
        camera, geometry::parse_pattern_spec(scenario.setup.plane_pattern), view_of(plane_photo),
        0);
    const auto stored =
        vision::find_reference_marks(view_of(plane_photo), "DICT_APRILTAG_36h11", camera);
    CHECK_EQUAL(4u, stored.marks.size());
    bench.take_board_away();

    // Found again in windows around the stored marks (as the cycle's check does): the same
    // corners as the whole photo's search gives.
    const auto still_photo = bench.photograph(1);
    const auto again = vision::find_reference_marks_again(view_of(still_photo), stored, camera);
    const auto whole =
        vision::find_reference_marks(view_of(still_photo), stored.dictionary, camera);
    CHECK_EQUAL(whole.marks.size(), again.marks.size());
    for (std::size_t m = 0; m < whole.marks.size(); ++m) {
        CHECK_EQUAL(whole.marks[m].id, again.marks[m].id);
        for (std::size_t k = 0; k < 4; ++k) {
            DOUBLES_EQUAL(whole.marks[m].corners[k].x, again.marks[m].corners[k].x, 0.01);
            DOUBLES_EQUAL(whole.marks[m].corners[k].y, again.marks[m].corners[k].y, 0.01);
        }
    }
    // A window that misses its mark (stored where the mark is not: here, the photo's middle)
    // sends the search to the whole photo: every mark found, where the whole photo's search has it.
    auto misplaced = stored;
    {
        auto& corners = misplaced.marks.front().corners;
        double cx = 0, cy = 0;
        for (const auto& p : corners) cx += p.x / 4, cy += p.y / 4;
        for (auto& p : corners)
            p.x += camera.image_width / 2.0 - cx, p.y += camera.image_height / 2.0 - cy;
    }
    const auto refound =
        vision::find_reference_marks_again(view_of(still_photo), misplaced, camera);
    CHECK_EQUAL(whole.marks.size(), refound.marks.size());
    for (std::size_t m = 0; m < whole.marks.size(); ++m) {
        CHECK_EQUAL(whole.marks[m].id, refound.marks[m].id);
        for (std::size_t k = 0; k < 4; ++k) {
            DOUBLES_EQUAL(whole.marks[m].corners[k].x, refound.marks[m].corners[k].x, 1e-9);
            DOUBLES_EQUAL(whole.marks[m].corners[k].y, refound.marks[m].corners[k].y, 1e-9);
        }
    }
    const auto still = vision::compare_reference(stored, again, camera, plane);
    CHECK_EQUAL(4, still.marks_compared);
    CHECK(still.missing.empty());
    // Two photos' noise, the board's bright paper beside the marks in the first: well under the
    // default limit (setup.camera_moved_limit_mm, 0.05 mm).
    CHECK_TEXT(still.largest_mm < 0.01, std::to_string(still.largest_mm).c_str());

    const sim::Pose before = sim::look_at_pose(
        scenario.camera->position_mm, scenario.camera->look_at_mm, scenario.camera->roll_deg);
    for (const double turn_deg : {0.004, 0.02, 0.1}) {
        sim::TwinBench knocked_bench(scenario);
        knocked_bench.knock_camera(turn_deg, {0, 0, 0});
        sim::Pose knock;
        knock.rotation = sim::rotation_from_vector(sim::Vec3{sim::radians(turn_deg), 0, 0});
        const sim::Pose after = sim::compose(knock, before);
        double truth = 0;
        const double half = scenario.setup.reference_mark_mm / 2;
        for (const auto& m : knocked_bench.reference_marks()) {
            for (const double dx : {-half, half}) {
                for (const double dy : {-half, half}) {
                    const sim::Vec3 p{m.centre_mm.x + dx, m.centre_mm.y + dy, 0};
                    const sim::Vec2 seen = apparent_on_bed(c, before, after, p);
                    truth = std::max(truth, std::hypot(seen.x - p.x, seen.y - p.y));
                }
            }
        }
        const auto move =
            vision::compare_reference(stored,
                                      vision::find_reference_marks_again(
                                          view_of(knocked_bench.photograph(2)), stored, camera),
                                      camera, plane);
        UT_PRINT(("turned " + std::to_string(turn_deg) + " deg: largest apparent move " +
                  std::to_string(move.largest_mm) + " mm, the twin's " + std::to_string(truth) +
                  " mm")
                     .c_str());
        CHECK_EQUAL(4, move.marks_compared);
        DOUBLES_EQUAL(truth, move.largest_mm, 0.005);
    }
}

TEST(ReferenceMarks, the_stored_view_round_trips_and_a_broken_one_is_refused) {
    vision::ReferenceView view{"DICT_APRILTAG_36h11", {}};
    view.marks.push_back({{{{{10.5, 20.25}, {30, 20}, {30, 40}, {10, 40.125}}}, true, {}, {}}, 3});
    view.marks.push_back({{{{{100, 200}, {130, 200}, {130, 240}, {100, 240}}}, true, {}, {}}, 7});
    const auto back = vision::reference_from_yaml(vision::reference_to_yaml(view));
    STRCMP_EQUAL("DICT_APRILTAG_36h11", back.dictionary.c_str());
    CHECK_EQUAL(2u, back.marks.size());
    CHECK_EQUAL(7, back.marks[1].id);
    DOUBLES_EQUAL(40.125, back.marks[0].corners[3].y, 0);
    DOUBLES_EQUAL(20.25, back.marks[0].corners[0].y, 0);

    const auto refused = [](const std::string& text) {
        try {
            (void)vision::reference_from_yaml(text);
        } catch (const geometry::FileFormatError& e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    STRCMP_CONTAINS("'dictionary'", refused("%YAML:1.0\n---\nmarks: []\n").c_str());
    STRCMP_CONTAINS("'marks'", refused("%YAML:1.0\n---\ndictionary: DICT_4X4_50\n").c_str());
    STRCMP_CONTAINS(
        "mark 2: 'corners' must be 8 numbers",
        refused("%YAML:1.0\n---\ndictionary: D\nmarks:\n  - { id: 2, corners: [1, 2, 3] }\n")
            .c_str());
    STRCMP_CONTAINS("not an OpenCV YAML file", refused("").c_str());
}

// A stored mark not found now is named; the others still give the move.
TEST(ReferenceMarks, a_mark_not_found_is_named) {
    const auto camera = as_core(hq_camera());
    geometry::BedPlane plane;
    plane.bed_to_camera.rvec = {M_PI, 0, 0};  // looking straight down from 400 mm
    plane.bed_to_camera.tvec_mm = {0, 0, 400};
    vision::ReferenceView stored{"DICT_4X4_50", {}};
    stored.marks.push_back({{{{{100, 100}, {200, 100}, {200, 200}, {100, 200}}}, true, {}, {}}, 1});
    stored.marks.push_back(
        {{{{{900, 100}, {1000, 100}, {1000, 200}, {900, 200}}}, true, {}, {}}, 2});
    vision::ReferenceView now = stored;
    now.marks.erase(now.marks.begin());
    for (auto& p : now.marks[0].corners) p.x += 1.0;  // one pixel right
    const auto move = vision::compare_reference(stored, now, camera, plane);
    CHECK_EQUAL(1, move.marks_compared);
    CHECK_EQUAL(1u, move.missing.size());
    CHECK_EQUAL(1, move.missing[0]);
    // One pixel at 400 mm through a lens of fx = hq_camera().fx, worked by hand.
    DOUBLES_EQUAL(400.0 / hq_camera().fx, move.largest_mm, 0.1 * 400.0 / hq_camera().fx);
}

// Issue 12: the two backends on the same AprilTag 36h11 markers (OpenCV's DICT_APRILTAG_36h11,
// libapriltag's tag36h11), small ones, under each of a real photo's troubles: how many each
// finds and how far its refined corners lie from the twin's truth. README: "AprilTag".
TEST_GROUP(MarkerBackends){};

TEST(MarkerBackends, opencv_and_libapriltag_recall_and_corner_error_on_harder_photos) {
    sim::CameraIntrinsics camera;
    camera.width_px = 1600;
    camera.height_px = 1200;
    camera.fx = camera.fy = 2850;  // 0.14 mm a pixel at 400 mm
    camera.cx = 801.3;
    camera.cy = 598.2;
    camera.distortion = {-0.05, 0.08, 0.0002, -0.0001, 0};
    struct Trouble {
        const char* name;
        sim::PhotoSettings photo;
    };
    sim::PhotoSettings plain;
    plain.noise_sigma_dn = 2;
    plain.blur_sigma_px = 0.7;
    plain.vignetting = 0.15;
    plain.lighting_gradient = 0.1;
    std::vector<Trouble> troubles{{"plain", plain}};
    troubles.push_back({"JPEG 93", plain});
    troubles.back().photo.jpeg_quality = 93;
    troubles.push_back({"motion blur 1.5 px", plain});
    troubles.back().photo.motion_blur_px = 1.5;
    troubles.back().photo.motion_blur_direction_deg = 30;
    troubles.push_back({"light from one side", plain});
    troubles.back().photo.lighting_gradient = 0.8;
    troubles.push_back({"dim and noisy", plain});
    troubles.back().photo.exposure_dn = 90;
    troubles.back().photo.noise_sigma_dn = 4;
    troubles.push_back({"all together", plain});
    troubles.back().photo.jpeg_quality = 93;
    troubles.back().photo.motion_blur_px = 1.0;
    troubles.back().photo.lighting_gradient = 0.5;
    troubles.back().photo.exposure_dn = 120;
    troubles.back().photo.noise_sigma_dn = 3;
    // 8x6 markers of 5 mm (36 px, 4.5 px a cell) and of 3 mm (21 px, 2.7 px a cell: where the
    // detectors begin to lose them), turned and tilted.
    for (const double marker_mm : {5.0, 3.0, 2.0}) {
        const sim::Pose board =
            sim::compose(sim::look_at_pose({0, -30, 400}, {0, 0, 0}, 0),
                         sim::board_lying_on_bed({-5.5 * marker_mm, 4 * marker_mm, 0}, 11));
        const sim::BoardScene scene(
            geometry::parse_pattern_spec("aruco:8x6@" + number_text("%g", marker_mm) + "/" +
                                         number_text("%g", 0.6 * marker_mm) +
                                         ":DICT_APRILTAG_36h11"),
            4);
        std::map<std::pair<int, int>, sim::Vec2> truth;
        for (const auto& f : scene.features())
            truth[{f.id, f.corner}] = sim::project_point(camera, board, f.position_mm);
        for (const auto& t : troubles) {
            const auto image = sim::render_photo(camera, board, scene, t.photo);
            std::string line = number_text("%g", marker_mm) + " mm, " + t.name + ":";
            std::size_t found_by[2] = {0, 0};
            int backend = 0;
            for (const char* dictionary : {"DICT_APRILTAG_36h11", "tag36h11"}) {
                vision::MarkerOptions options;
                options.dictionary = dictionary;
                const auto found = vision::detect_markers(view_of(image), options);
                found_by[backend++] = found.size();
                double sum = 0;
                int n = 0;
                for (const auto& m : found) {
                    for (std::size_t k = 0; k < 4; ++k) {
                        const auto at = truth.find({m.id, static_cast<int>(k)});
                        CHECK_TEXT(at != truth.end(), "a marker the board does not have");
                        if (at == truth.end()) continue;
                        sum += std::pow(m.corners[k].x - at->second.x, 2) +
                               std::pow(m.corners[k].y - at->second.y, 2);
                        ++n;
                    }
                }
                const double rms = std::sqrt(sum / std::max(1, n));
                line += std::string(" ") + dictionary + " " + std::to_string(found.size()) +
                        "/48 " + number_text("%.3f", rms) + " px;";
                CHECK_TEXT(rms < (marker_mm == 5.0   ? 0.1
                                  : marker_mm == 3.0 ? 0.2
                                                     : 0.35),
                           line.c_str());
            }
            // libapriltag as its own default has it: one pass at half resolution.
            vision::MarkerOptions halved;
            halved.dictionary = "tag36h11";
            halved.apriltag_limits.quad_decimate = 2;
            halved.apriltag_limits.second_pass_decimate = 0;
            const std::size_t found_halved = vision::detect_markers(view_of(image), halved).size();
            line += " tag36h11 at half resolution alone " + std::to_string(found_halved) + "/48";
            UT_PRINT(line.c_str());
            // The 5 mm markers: every one on every photo, by both. The 3 mm ones: libapriltag
            // still every one (OpenCV 26 to 42 of them, README). The 2 mm ones (1.75 px a
            // cell), full resolution and half together: at least as many as half resolution
            // alone, and nearly all where the photo is sharp and bright.
            if (marker_mm == 5.0) CHECK_TEXT(found_by[0] == 48, line.c_str());
            if (marker_mm >= 3.0) CHECK_TEXT(found_by[1] == 48, line.c_str());
            if (marker_mm == 2.0) {
                CHECK_TEXT(found_by[1] >= found_halved, line.c_str());
                if (std::string(t.name) == "plain" || std::string(t.name) == "JPEG 93" ||
                    std::string(t.name) == "light from one side")
                    CHECK_TEXT(found_by[1] >= 45 && found_halved <= 20, line.c_str());
            }
        }
    }
}

// Marks found whatever surrounds the work: a sheet of dark holes filling 30 to 90 % of the frame
// against a dark bed, a grey floor and a white table, the holes 8 to 40 px across. A straight
// camera at 0.5 mm a pixel, a slight tilt so that the scale differs across the frame.
TEST_GROUP(MarkSurroundings){};

namespace {

// An 800 x 600 camera without distortion 400 mm over the bed (0.5 mm a pixel), at `pose`, and the
// bed plane as the twin has it (what is tested is the marks, not the board).
struct PlainBench {
    sim::CameraIntrinsics lens;
    sim::Pose pose;
    geometry::CameraModel camera;
    geometry::BedPlane plane;
};

PlainBench plain_bench(const sim::Pose& pose) {
    PlainBench b;
    b.lens.width_px = 800, b.lens.height_px = 600;
    b.lens.fx = b.lens.fy = 800;
    b.lens.cx = 399.5, b.lens.cy = 299.5;
    b.lens.distortion = {0, 0, 0, 0, 0};
    b.pose = pose;
    b.camera = as_core(b.lens);
    const sim::Vec3 r = sim::vector_from_rotation(pose.rotation);
    b.plane.bed_to_camera.rvec = {r.x, r.y, r.z};
    b.plane.bed_to_camera.tvec_mm = {pose.translation_mm.x, pose.translation_mm.y,
                                     pose.translation_mm.z};
    return b;
}

}  // namespace

TEST(MarkSurroundings, every_hole_is_found_and_none_set_aside_for_its_size) {
    const PlainBench bench = plain_bench(sim::look_at_pose({12, -9, 400}, {0, 0, 0}, 4));
    const auto& lens = bench.lens;
    const auto& pose = bench.pose;
    const auto& camera = bench.camera;
    const auto& plane = bench.plane;
    sim::PhotoSettings photo;
    photo.blur_sigma_px = 0.8, photo.noise_sigma_dn = 2;
    const double mm_per_px = 0.5;
    int cases = 0;
    for (const double share : {0.3, 0.6, 0.9})
        for (const double surroundings : {0.05, 0.45, 0.97})
            for (const double hole_px : {8.0, 16.0, 40.0}) {
                const double half_w = 0.5 * 400 * std::sqrt(share) * 0.98;
                const double half_h = 0.5 * 300 * std::sqrt(share) * 0.98;
                const double diameter_mm = hole_px * mm_per_px, pitch_mm = 3 * diameter_mm;
                std::vector<sim::StrokeSegment> holes;
                for (double y = -half_h + pitch_mm; y <= half_h - pitch_mm; y += pitch_mm)
                    for (double x = -half_w + pitch_mm; x <= half_w - pitch_mm; x += pitch_mm)
                        holes.push_back({{x, y, 0}, {x, y, 0}, diameter_mm});
                const sim::StrokeScene sheet(holes, 0.82, 0.1, 4, 1.0);
                const test::SurroundedScene scene(sheet,
                                                  {-half_w, -half_h, half_w, half_h, surroundings});
                photo.seed = static_cast<unsigned>(++cases);
                const auto image = sim::render_photo(lens, pose, scene, photo);
                vision::SpotSettings settings;
                settings.polarity = vision::MarkPolarity::dark;
                settings.mark_diameter_px =
                    diameter_mm * modes::pixels_per_mm_at_centre(camera, plane, 0);
                const auto seen = vision::find_spots(view_of(image), settings);
                std::vector<modes::MarkCandidate> candidates;
                for (const auto& m : modes::marks_on_bed(camera, plane, seen, 0)) {
                    const double nominal = 0.5 * diameter_mm;
                    if (m.touches_border || m.elongation > 1.08 || m.radius_mm < 0.7 * nominal ||
                        m.radius_mm > 1.3 * nominal)
                        continue;
                    candidates.push_back({m.bed_mm, m.radius_mm, m.sigma_mm, false, false});
                }
                const std::string what =
                    number_text("%.0f %% of the frame, surroundings ", 100 * share) +
                    number_text("%.2f, holes ", surroundings) + number_text("%.0f px: ", hole_px) +
                    std::to_string(candidates.size()) + " of " + std::to_string(holes.size()) +
                    " found";
                CHECK_TEXT(candidates.size() == holes.size(), what.c_str());
                std::vector<geometry::Point2> set_aside;
                modes::set_aside_odd_sizes(candidates, 0.05, set_aside);
                CHECK_TEXT(set_aside.empty(), (what + ", " + std::to_string(set_aside.size()) +
                                               " set aside for their size")
                                                  .c_str());
            }
}

// The search limited to where the work can be: dots of the holes' own size on the surroundings,
// past the outline, are not looked at; without the outline they would pass for holes.
TEST(MarkSurroundings, blobs_past_the_work_outline_are_not_looked_at) {
    const PlainBench bench = plain_bench(sim::look_at_pose({0, 0, 400}, {0, 0, 0}, 0));
    const auto& lens = bench.lens;
    const auto& pose = bench.pose;
    const auto& camera = bench.camera;
    const auto& plane = bench.plane;
    // The outline of a 60 mm reach: a circle 120 px in radius about the image's middle.
    const auto outline = modes::work_outline_px(camera, plane, 0, 60);
    CHECK_EQUAL(72u, outline.size());
    for (const auto& p : outline) DOUBLES_EQUAL(120, std::hypot(p.x - 399.5, p.y - 299.5), 0.5);
    // Holes of 8 mm within 40 mm of the middle, and decoys of the same size 120 mm out.
    std::vector<sim::StrokeSegment> dots;
    for (const double a : {0.0, 1.5, 3.0, 4.5})
        dots.push_back(
            {{40 * std::cos(a), 40 * std::sin(a), 0}, {40 * std::cos(a), 40 * std::sin(a), 0}, 8});
    for (const double x : {-150.0, 150.0}) dots.push_back({{x, 100, 0}, {x, 100, 0}, 8});
    sim::PhotoSettings photo;
    photo.blur_sigma_px = 0.8, photo.noise_sigma_dn = 2;
    const auto image =
        sim::render_photo(lens, pose, sim::StrokeScene(dots, 0.82, 0.1, 4, 1.0), photo);
    vision::SpotSettings settings;
    settings.mark_diameter_px = 16;
    CHECK_EQUAL(6u, vision::find_spots(view_of(image), settings).spots.size());
    settings.search_outline_px = outline;
    CHECK_EQUAL(4u, vision::find_spots(view_of(image), settings).spots.size());
}

TEST_GROUP(Glare){};

namespace {

// How far the bed lies from the camera along the bed's normal: the plane's scale.
double camera_height_mm(const geometry::BedPlane& plane) {
    const auto& r = plane.bed_to_camera.rvec;
    const sim::Mat3 rotation = sim::rotation_from_vector({r[0], r[1], r[2]});
    const sim::Vec3 normal = rotation * sim::Vec3{0, 0, 1};
    const auto& t = plane.bed_to_camera.tvec_mm;
    return std::abs(normal.x * t[0] + normal.y * t[1] + normal.z * t[2]);
}

}  // namespace

// The plane's board laminated and under the box's lamp, whose reflection washes out some of its
// squares (a tenth of the frame clipped white), seen through a lens with soft corners, uneven
// light, three times the noise and JPEG at 68: found, the corners under the glare set aside and
// named, and the plane's scale within 0.05 % of the clean photo's.
TEST(Glare, a_laminated_board_under_the_lamp_is_found_at_the_clean_boards_scale) {
    struct Seen {
        double clipped_share;
        std::optional<geometry::BedPlane> plane;
        std::string refusal;
    };
    const auto plane_of = [](const std::string& scenario_file, double strength) {
        auto scenario = sim::load_scenario(std::string(CALBOX_SOURCE_DIR) + "/tests/scenarios/" +
                                           scenario_file);
        scenario.glare_strength = strength;
        sim::TwinBench bench(scenario);
        bench.lay_plane_board_on_bed();
        const auto photo = bench.photograph(0);
        Seen seen{0, std::nullopt, ""};
        for (const auto p : photo.pixels) seen.clipped_share += p >= 250 ? 1 : 0;
        seen.clipped_share /= static_cast<double>(photo.pixels.size());
        try {
            seen.plane = geometry::estimate_bed_plane(
                sim::as_camera_model(scenario.camera->intrinsics),
                geometry::parse_pattern_spec(scenario.setup.plane_pattern), view_of(photo), 0);
        } catch (const geometry::CalibrationError& e) {
            seen.refusal = e.what();
        }
        return seen;
    };
    const auto clean = plane_of("delta_cycle_small.toml", 1);
    CHECK(clean.plane.has_value());
    if (!clean.plane) return;
    CHECK(clean.plane->set_aside_corners.empty());
    const double clean_mm = camera_height_mm(*clean.plane);
    DOUBLES_EQUAL(400, clean_mm, 0.02);  // the twin's camera stands 400 mm over the bed
    // The scenario's strength is the one that stopped the set-up before the equalised search: a
    // tenth of the frame clipped.
    const auto worst = plane_of("delta_worst_day.toml", 1.0);
    CHECK(worst.clipped_share > 0.08 && worst.clipped_share < 0.15);
    for (const auto& [strength, glossy] :
         {std::pair{0.5, plane_of("delta_worst_day.toml", 0.5)}, std::pair{1.0, worst}}) {
        const std::string what = "glare at " + std::to_string(strength) + ": " +
                                 std::to_string(100 * glossy.clipped_share) + " % clipped";
        CHECK_TEXT(glossy.plane.has_value(), (what + ", " + glossy.refusal).c_str());
        if (!glossy.plane) continue;
        const double height_mm = camera_height_mm(*glossy.plane);
        UT_PRINT((what + geometry::set_aside_text(*glossy.plane) + "; camera " +
                  std::to_string(height_mm) + " mm over the bed, the clean photo's " +
                  std::to_string(clean_mm))
                     .c_str());
        CHECK_TEXT(std::abs(height_mm / clean_mm - 1) < 0.0005, what.c_str());
        CHECK_TEXT(glossy.plane->rms_px < 0.3, what.c_str());
        CHECK_TEXT(glossy.plane->corners_used >= 27, what.c_str());
    }
    // At full strength the lamp's spot washes out some of the corners: set aside and named.
    if (worst.plane) CHECK(!worst.plane->set_aside_corners.empty());
    // Twice as strong, the board is lost under the glare, and the refusal says so.
    const auto blinding = plane_of("delta_worst_day.toml", 2.0);
    CHECK_FALSE(blinding.plane.has_value());
    STRCMP_CONTAINS("clipped white", blinding.refusal.c_str());
    STRCMP_CONTAINS("diffuse", blinding.refusal.c_str());
}

// A ChArUco board, for an owner who prefers one: each corner identified by its markers, so the
// squares the lamp washes out drop out alone and the rest give the plane. On the worst day's
// laminated board under the lamp, the plane's scale within 0.05 % of the same board's matte.
TEST(Glare, a_charuco_board_under_the_lamp_gives_the_plane_from_the_corners_it_still_shows) {
    const auto scenario = sim::load_scenario(std::string(CALBOX_SOURCE_DIR) +
                                             "/tests/scenarios/delta_worst_day.toml");
    const auto& c = scenario.camera->intrinsics;
    const sim::Pose bed_to_camera = sim::look_at_pose(
        scenario.camera->position_mm, scenario.camera->look_at_mm, scenario.camera->roll_deg);
    const std::string spec_text = "charuco:10x7@20/15:DICT_5X5_100";
    const auto spec = geometry::parse_pattern_spec(spec_text);
    const sim::Pose board_to_camera =
        sim::compose(bed_to_camera, sim::board_lying_on_bed({-100, 70, 0}, 0));
    const auto plane_under = [&](const std::string& surface, int& corners_used) {
        auto lit = scenario;
        lit.board_surface = surface;
        const auto photo = sim::render_photo(c, board_to_camera, sim::BoardScene(spec, 4),
                                             sim::photo_settings_of(lit, sim::InView::board));
        double clipped = 0;
        for (const auto p : photo.pixels) clipped += p >= 250 ? 1 : 0;
        const auto plane =
            geometry::estimate_bed_plane(sim::as_camera_model(c), spec, view_of(photo), 0);
        corners_used = plane.corners_used;
        UT_PRINT((surface + ": " + std::to_string(100 * clipped / photo.pixels.size()) +
                  " % clipped, " + std::to_string(plane.corners_used) + " corners, camera " +
                  std::to_string(camera_height_mm(plane)) + " mm over the bed")
                     .c_str());
        return camera_height_mm(plane);
    };
    int matte_corners = 0, glossy_corners = 0;
    const double matte_mm = plane_under("matte", matte_corners);
    const double glossy_mm = plane_under("laminated", glossy_corners);
    DOUBLES_EQUAL(400, matte_mm, 0.02);
    CHECK(glossy_corners < matte_corners);  // the washed-out squares' corners drop out
    CHECK(glossy_corners >= matte_corners / 2);
    CHECK_TEXT(std::abs(glossy_mm / matte_mm - 1) < 0.0005, std::to_string(glossy_mm).c_str());
}

// A glow over most of the board (a lamp's reflection off a broad sheen): the board is still found,
// but more than half of its corners are washed out, and the plane is refused rather than fitted
// on the few left.
TEST(Glare, a_board_mostly_washed_out_is_refused_with_the_share) {
    const auto scenario = sim::load_scenario(std::string(CALBOX_SOURCE_DIR) +
                                             "/tests/scenarios/delta_cycle_small.toml");
    sim::TwinBench bench(scenario);
    bench.lay_plane_board_on_bed();
    auto photo = bench.photograph(0);
    const double centre_u = photo.width_px * 0.55, centre_v = photo.height_px * 0.5;
    for (int v = 0; v < photo.height_px; ++v) {
        for (int u = 0; u < photo.width_px; ++u) {
            auto& p = photo.pixels[static_cast<std::size_t>(v) * photo.width_px + u];
            const double r2 = (u - centre_u) * (u - centre_u) + (v - centre_v) * (v - centre_v);
            p = static_cast<std::uint8_t>(
                std::min(255.0, p + 240 * std::exp(-r2 / (2 * 700.0 * 700.0))));
        }
    }
    const auto pattern = geometry::parse_pattern_spec(scenario.setup.plane_pattern);
    const auto found = geometry::find_board(pattern, view_of(photo));
    CHECK(found.has_value());
    if (!found) return;
    CHECK_TEXT(2 * found->set_aside_ids.size() > found->ids.size() + found->set_aside_ids.size(),
               std::to_string(found->set_aside_ids.size()).c_str());
    try {
        geometry::estimate_bed_plane(sim::as_camera_model(scenario.camera->intrinsics), pattern,
                                     view_of(photo), 0);
        FAIL("a plane from a board mostly washed out");
    } catch (const geometry::CalibrationError& e) {
        UT_PRINT(e.what());
        STRCMP_CONTAINS("found under glare", e.what());
    }
}

// The fixed reference marks stand near the view's corners, where a lens with a curved field is
// softest: on the worst day (5 px more blur there, vignetting, noise, JPEG) OpenCV's detector
// finds none of the four AprilTag marks; libapriltag, reading the same codes, finds them all,
// each where the twin's camera puts its centre.
TEST(Glare, reference_marks_in_soft_corners_are_found_where_the_twin_puts_them) {
    const auto scenario = sim::load_scenario(std::string(CALBOX_SOURCE_DIR) +
                                             "/tests/scenarios/delta_worst_day.toml");
    sim::TwinBench bench(scenario);
    bench.lay_plane_board_on_bed();
    const auto photo = bench.photograph(0);
    const auto& c = scenario.camera->intrinsics;
    const auto camera = sim::as_camera_model(c);
    const auto found = vision::find_reference_marks(view_of(photo), "DICT_APRILTAG_36h11", camera);
    CHECK_EQUAL(4u, found.marks.size());
    const sim::Pose bed_to_camera = sim::look_at_pose(
        scenario.camera->position_mm, scenario.camera->look_at_mm, scenario.camera->roll_deg);
    for (const auto& mark : found.marks) {
        CHECK(mark.id >= 0 && mark.id < 4);
        const auto& truth = bench.reference_marks()[static_cast<std::size_t>(mark.id)];
        const sim::Vec2 centre = sim::project_point(
            c, bed_to_camera, sim::Vec3{truth.centre_mm.x, truth.centre_mm.y, 0});
        double x = 0, y = 0;
        for (const auto& corner : mark.corners) {
            x += corner.x / 4;
            y += corner.y / 4;
        }
        // Under 5.7 px of blur the edge refinement refuses most of these corners (they move
        // more than 2 px from the detector's) and the detector's rough corners are kept: a mark
        // stands within 1.5 px of where the twin put it (a sharp one within a few hundredths).
        CHECK_TEXT(std::hypot(x - centre.x, y - centre.y) < 1.5,
                   ("mark " + std::to_string(mark.id) + " " +
                    std::to_string(std::hypot(x - centre.x, y - centre.y)) + " px off")
                       .c_str());
    }
}

// A burned mark on a glass plate under the lamp: the lamp's mirrored lobe (added to the plate's
// and the mark's albedo alike) climbs about 4 counts a pixel across the mark. Drawn here by hand:
// a disc of albedo 0.1 on 0.8, each pixel's cover from 16 x 16 samples, 150 counts per unit of
// albedo, the lobe 1.5 units high and 25 px wide 40 px from the mark. Its centre is found where
// it was drawn (within 0.07 px); the substrate held at one level, its true level at the mark's
// centre, pulls it more than a pixel towards the lobe's dim side.
TEST(Glare, a_mark_on_a_glossy_plate_is_centred_however_steeply_the_glare_climbs_across_it) {
    constexpr int kSide = 96;
    const double cx = 40.37, cy = 47.81, radius = 9.0;
    const double lobe_x = 75, lobe_y = 28, lobe_px = 25, lobe_peak = 1.5, counts = 150;
    std::vector<std::uint8_t> pixels(kSide * kSide);
    for (int y = 0; y < kSide; ++y)
        for (int x = 0; x < kSide; ++x) {
            int inside = 0;
            for (int j = 0; j < 16; ++j)
                for (int i = 0; i < 16; ++i) {
                    const double sx = x - 0.5 + (i + 0.5) / 16, sy = y - 0.5 + (j + 0.5) / 16;
                    inside += (sx - cx) * (sx - cx) + (sy - cy) * (sy - cy) <= radius * radius;
                }
            const double cover = inside / 256.0;
            const double d2 = (x - lobe_x) * (x - lobe_x) + (y - lobe_y) * (y - lobe_y);
            const double glare = lobe_peak * std::exp(-d2 / (2 * lobe_px * lobe_px));
            const double albedo = 0.8 * (1 - cover) + 0.1 * cover + glare;
            pixels[static_cast<std::size_t>(y * kSide + x)] =
                static_cast<std::uint8_t>(std::clamp(std::lround(counts * albedo), 0L, 255L));
        }
    const vision::GrayView view{pixels.data(), kSide, kSide, kSide};
    vision::SpotSettings settings;
    settings.mark_diameter_px = 2 * radius;
    const auto seen = vision::find_spots(view, settings);
    // The lobe's own shoulders pass the local level too (the modes set such blobs aside by size
    // and shape): the mark is the one of its size.
    const auto mark = std::find_if(seen.spots.begin(), seen.spots.end(), [&](const auto& s) {
        return std::abs(s.area_px - 3.14159265 * radius * radius) <
               0.2 * 3.14159265 * radius * radius;
    });
    CHECK(mark != seen.spots.end());
    const auto& spot = *mark;
    const double off_px = std::hypot(spot.centre_px.x - cx, spot.centre_px.y - cy);
    // What is left (0.05 px) is the lobe's curvature, which a plane does not follow.
    CHECK_TEXT(off_px < 0.07, number_text("%.3f px off", off_px).c_str());
    DOUBLES_EQUAL(3.14159265 * radius * radius, spot.area_px, 0.03 * 3.14159265 * radius * radius);

    // The bias the plane removes, measured with the kernel the finder uses.
    vision::MomentWindow flat;
    flat.centre_px = {cx, cy};
    flat.radius_px = radius + settings.window_margin_px;
    double lobe_at_centre =
        lobe_peak * std::exp(-((cx - lobe_x) * (cx - lobe_x) + (cy - lobe_y) * (cy - lobe_y)) /
                             (2 * lobe_px * lobe_px));
    flat.substrate_dn = counts * (0.8 + lobe_at_centre);
    flat.mark_dn = counts * (0.1 + lobe_at_centre);
    flat.noise_dn = 1;
    const auto held = vision::measure_spot_q16(view, flat);
    const double held_off_px = std::hypot(held.centre_px.x - cx, held.centre_px.y - cy);
    CHECK_TEXT(held_off_px > 1.0, number_text("%.3f px off held flat", held_off_px).c_str());
}

// A strand's width under a lens's blur: profiles worked out by hand (a bar of known width through
// a Gaussian blur, on a sloping background, with the sensor's noise).
TEST_GROUP(StrandWidth){
    // A bright bar `width_px` wide centred at `centre_px`, blurred by `blur_px`, sampled every
    // quarter pixel over 16 px, 60 grey levels of bed rising 0.5 a pixel, the strand 80 above.
    static std::vector<double> blurred_bar(double centre_px, double width_px, double blur_px,
                                           double noise_dn, unsigned seed){std::mt19937 rng(seed);
std::normal_distribution<double> noise(0, noise_dn);
std::vector<double> profile;
for (double x = 0; x <= 16; x += 0.25) {
    const double a = (x - centre_px + width_px / 2) / (blur_px * std::sqrt(2.0));
    const double b = (x - centre_px - width_px / 2) / (blur_px * std::sqrt(2.0));
    profile.push_back(60 + 0.5 * x + 80 * (std::erf(a) - std::erf(b)) / 2 + noise(rng));
}
return profile;
}
}
;

TEST(StrandWidth, the_blurred_bar_fit_gives_the_width_and_the_blur) {
    for (const double blur : {0.5, 1.0, 1.5, 2.0, 2.5}) {
        const auto bar =
            vision::fit_blurred_bar(blurred_bar(7.9, 3.2, blur, 0, 1), 0.25, {7.5, 4.0, 1.0, 70});
        CHECK_TEXT(bar.has_value(), std::to_string(blur).c_str());
        DOUBLES_EQUAL(3.2, bar->width_px, 1e-4);
        DOUBLES_EQUAL(7.9, bar->centre_px, 1e-4);
        DOUBLES_EQUAL(blur, bar->blur_sigma_px, 1e-4);
        DOUBLES_EQUAL(80, bar->contrast_dn, 1e-3);
    }
}

// A side's 40 profiles at a camera's worst noise (6 grey levels): averaged, they tell the blur
// and the brightness within a few hundredths; each profile's width, fitted with those held,
// scatters by a fifth of a pixel or less, their mean within a tenth of the true one wherever the
// blur is under the share of the width the ring allows (the edge kernel's centroids widen it by
// 0.19 px at 1 px of blur); past that share the blur is told above it.
TEST(StrandWidth, a_sides_profiles_tell_the_blur_and_each_its_width) {
    const vision::StrandRingLimits limits;
    for (const double blur : {0.5, 0.7, 1.0, 1.5, 2.0}) {
        std::vector<vision::StrandCrossing> crossings;
        for (unsigned seed = 0; seed < 40; ++seed) {
            vision::StrandCrossing c;
            // Each profile's middle where its edges' centroids put it: a few hundredths off.
            c.profile = blurred_bar(7.9 + 0.01 * (seed % 5), 3.2, blur, 6, seed + 10);
            c.profile_step_px = 0.25;
            c.middle_px = 7.9;
            c.width_px = 3.4;
            c.contrast_dn = 70;
            crossings.push_back(std::move(c));
        }
        std::string why_not;
        const auto side = vision::strand_across_side(crossings, limits, why_not);
        if (blur > limits.widest_blur_share * 3.2) {
            // Past the share, the ring tells no width: the blur is told above it, or not at all.
            CHECK(!side || side->blur_sigma_px > limits.widest_blur_share * 3.4);
            continue;
        }
        CHECK_TEXT(side.has_value(), why_not.c_str());
        DOUBLES_EQUAL(blur, side->blur_sigma_px, 0.05 * blur);
        DOUBLES_EQUAL(80, side->contrast_dn, 80 * 0.04);
        double sum = 0, sum_sq = 0;
        for (const auto& c : crossings) {
            const auto held = vision::fit_blurred_bar(
                c.profile, c.profile_step_px,
                {c.middle_px, c.width_px, side->blur_sigma_px, side->contrast_dn},
                vision::BarFit::contrast_and_blur_held);
            CHECK(held.has_value());
            DOUBLES_EQUAL(side->blur_sigma_px, held->blur_sigma_px, 1e-12);
            sum += held->width_px;
            sum_sq += held->width_px * held->width_px;
        }
        const double mean = sum / 40;
        const double spread = std::sqrt(std::max(0.0, sum_sq / 40 - mean * mean));
        UT_PRINT(("blur " + std::to_string(blur) + " px: told " +
                  std::to_string(side->blur_sigma_px) + " px, brightness " +
                  std::to_string(side->contrast_dn) + "; widths " + std::to_string(mean) +
                  " px, spread " + std::to_string(spread))
                     .c_str());
        CHECK(spread < 0.2);
        DOUBLES_EQUAL(3.2, mean, 0.1);
    }
    // Too few profiles for a side's fit: said.
    std::string why_not;
    CHECK_FALSE(vision::strand_across_side({}, limits, why_not).has_value());
    STRCMP_EQUAL("the strand in 0 profiles (at least 8 needed for its blur)", why_not.c_str());
}

// The box's exposure, on frames worked out by hand.
TEST_GROUP(Metering) {
    // A 200 x 100 frame: its left half at `left_dn`, its right half at `right_dn`, with a dark
    // mark (10 DN, 6 x 6 px) every 20 px across both: a share of each tile under its 90th
    // percentile.
    static std::vector<std::uint8_t> two_halves(int left_dn, int right_dn) {
        std::vector<std::uint8_t> pixels(200 * 100);
        for (int y = 0; y < 100; ++y)
            for (int x = 0; x < 200; ++x) {
                const bool mark = x % 20 < 6 && y % 20 < 6;
                pixels[static_cast<std::size_t>(y * 200 + x)] =
                    static_cast<std::uint8_t>(mark ? 10 : (x < 100 ? left_dn : right_dn));
            }
        return pixels;
    }
    static vision::GrayView view(const std::vector<std::uint8_t>& pixels) {
        return {pixels.data(), 200, 100, 200};
    }
    // The frame less a 10 px border, where a work area's edge would be.
    const std::vector<geometry::Point2> area{{10, 10}, {189, 10}, {189, 89}, {10, 89}};
};

TEST(Metering, an_even_scene_gets_one_exposure_putting_its_bright_side_at_the_target) {
    const auto pixels = two_halves(100, 150);
    const auto light = vision::meter_work_area(view(pixels), area);
    DOUBLES_EQUAL(150, light.bright_dn, 0);
    DOUBLES_EQUAL(100, light.dark_dn, 0);
    DOUBLES_EQUAL(0, light.clipped_share, 0);
    CHECK_EQUAL(180u * 80u, light.pixels);
    const auto plan = vision::plan_exposure(light);
    CHECK(plan.step == vision::ExposurePlan::Step::single);
    DOUBLES_EQUAL(225.0 / 150, plan.ratio, 1e-12);
    STRCMP_EQUAL(
        "the work area's bright side 150, its dark side 100 (0.0 % clipped): x1.50 puts "
        "them at 225 and 150",
        plan.why.c_str());
    // At 85 % of the target or above, unclipped, a frame is held as it is.
    const auto held =
        vision::plan_exposure(vision::meter_work_area(view(two_halves(100, 200)), area));
    CHECK(held.step == vision::ExposurePlan::Step::single);
    DOUBLES_EQUAL(1, held.ratio, 0);
    STRCMP_CONTAINS(": held as it is", held.why.c_str());
}

TEST(Metering, a_clipped_bright_side_is_read_again_at_half_the_exposure) {
    const auto pixels = two_halves(100, 255);
    const auto light = vision::meter_work_area(view(pixels), area);
    DOUBLES_EQUAL(255, light.bright_dn, 0);
    // The right half less its marks, inside the area: 90 of its 180 columns, 80 rows, and the
    // marks there (columns 100-105, 120-125, ..., 180-185 over rows 20-25, ..., 80-85).
    const double right_marks = 5 * 6 * 4 * 6;
    DOUBLES_EQUAL((90 * 80 - right_marks) / (180.0 * 80), light.clipped_share, 1e-12);
    const auto plan = vision::plan_exposure(light);
    CHECK(plan.step == vision::ExposurePlan::Step::meter_again);
    DOUBLES_EQUAL(0.5, plan.ratio, 0);
}

TEST(Metering, a_dark_side_one_exposure_cannot_lift_is_bracketed_and_merged) {
    const auto pixels = two_halves(12, 220);
    const auto light = vision::meter_work_area(view(pixels), area);
    DOUBLES_EQUAL(12, light.dark_dn, 0);  // over half the tiles lie in the dim half
    const auto plan = vision::plan_exposure(light);
    CHECK(plan.step == vision::ExposurePlan::Step::bracket);
    DOUBLES_EQUAL(25.0 / 12, plan.ratio, 1e-12);  // the dark side at 25
    DOUBLES_EQUAL(1, plan.short_ratio, 0);        // the bright side already near the target
    // Where the long exposure would not give the dark side half as much light again, one is
    // taken (a black bed's bare stretches).
    CHECK(vision::plan_exposure(vision::meter_work_area(view(two_halves(20, 220)), area)).step ==
          vision::ExposurePlan::Step::single);
    // A long frame at twice the short one's light, clipped at 255 where that is over.
    std::vector<std::uint8_t> long_pixels(pixels.size());
    for (std::size_t i = 0; i < pixels.size(); ++i)
        long_pixels[i] = static_cast<std::uint8_t>(std::min(255, 2 * pixels[i]));
    const auto merged = vision::merge_bracket(view(long_pixels), view(pixels), 2.0);
    CHECK_EQUAL(200, merged.width_px);
    // Every pixel comes back at the short frame's level: the left half and the marks from the
    // long frame halved, the right half (440, clipped) from the short one.
    for (std::size_t i = 0; i < pixels.size(); ++i) CHECK_EQUAL(pixels[i], merged.pixels[i]);
    const double right_marks = 5 * 5 * 6 * 6;
    DOUBLES_EQUAL((100 * 100 - right_marks) / 20000.0, merged.from_short_share, 1e-12);
    CHECK_THROWS(std::invalid_argument,
                 vision::merge_bracket(view(pixels), view(long_pixels), 0.5));
}

// A glass plate's hot spot: a 30 x 30 px square at 220 on a work area at 60, read after the
// exposure was cut for it. The bright side holds the single exposure where it is, and the middle
// of the work area would stay at a quarter of the target: the long exposure puts it there, the
// hot spot comes from the short one.
TEST(Metering, a_small_hot_spot_does_not_hold_the_whole_work_area_down) {
    std::vector<std::uint8_t> pixels(200 * 100, 60);
    for (int y = 40; y < 70; ++y)
        for (int x = 120; x < 150; ++x) pixels[static_cast<std::size_t>(y * 200 + x)] = 220;
    const auto light = vision::meter_work_area(view(pixels), area);
    DOUBLES_EQUAL(220, light.bright_dn, 0);
    DOUBLES_EQUAL(60, light.typical_dn, 0);
    // A black bed with a bright print looks the same to one reading: only after the exposure
    // was cut for the hot spot is the dim middle the cut's doing.
    CHECK(vision::plan_exposure(light).step == vision::ExposurePlan::Step::single);
    const auto plan = vision::plan_exposure(light, {}, true);
    CHECK(plan.step == vision::ExposurePlan::Step::bracket);
    DOUBLES_EQUAL(225.0 / 60, plan.ratio, 1e-12);
    DOUBLES_EQUAL(1, plan.short_ratio, 0);
    STRCMP_CONTAINS("x3.75 for the work area's middle (60 there), x1.00 for the bright, merged",
                    plan.why.c_str());
}

TEST(Metering, a_work_area_off_the_frame_or_without_corners_is_refused) {
    const auto pixels = two_halves(100, 180);
    CHECK_THROWS(std::invalid_argument, vision::meter_work_area(view(pixels), {{1, 1}, {5, 5}}));
    CHECK_THROWS(std::invalid_argument,
                 vision::meter_work_area(view(pixels), {{300, 300}, {400, 300}, {400, 400}}));
}

// Otsu's level from a histogram the caller already has is OpenCV's THRESH_OTSU level on the same
// photo, over every photo OpenCV's documentation ships (real scenes, every kind of histogram), and
// on hand-made ones: two levels, one level (no split: 0), and an empty histogram.
TEST(Metering, otsus_level_from_a_histogram_is_opencvs_on_the_same_photo) {
    const std::string data = "/usr/share/doc/opencv-doc/examples/data/";
    int photos = 0;
    for (const char* name :
         {"HappyFish.jpg", "LinuxLogo.jpg", "aero1.jpg", "baboon.jpg", "box.png", "building.jpg",
          "chessboard.png", "fruits.jpg", "lena.jpg", "messi5.jpg", "pic1.png", "sudoku.png"}) {
        const cv::Mat photo = cv::imread(data + name, cv::IMREAD_GRAYSCALE);
        if (photo.empty()) continue;
        ++photos;
        std::array<double, 256> histogram{};
        for (int y = 0; y < photo.rows; ++y)
            for (int x = 0; x < photo.cols; ++x) ++histogram[photo.at<std::uint8_t>(y, x)];
        cv::Mat ignored;
        const double opencv =
            cv::threshold(photo, ignored, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
        LONGS_EQUAL_TEXT(static_cast<long>(opencv), vision::otsu_level(histogram), name);
    }
    CHECK(photos >= 10);
    std::array<double, 256> two{};
    two[40] = 300, two[200] = 100;
    LONGS_EQUAL(40, vision::otsu_level(two));
    std::array<double, 256> one{};
    one[128] = 5;
    LONGS_EQUAL(0, vision::otsu_level(one));
    LONGS_EQUAL(0, vision::otsu_level(std::array<double, 256>{}));
}
