// The reference marks the box fixes its camera's pose by, and the marker detectors behind
// one interface (calbox's own, OpenCV's ArUco, AprilTag), judged against the renderer's truth.
#include "tests/unit/vision_scenes.hpp"

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
