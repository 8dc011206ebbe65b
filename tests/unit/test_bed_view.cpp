// The bed as the machine sees it (core/modes/bed_view): a photo projected onto the machine's
// coordinates through the camera, the bed plane and the planar result; judged by where the twin
// router's tool really goes, and the view's corners found by OpenCV's own chessboard detector.
#include "tests/unit/bed_view_rig.hpp"

TEST_GROUP(BedViewFrame){};

// The solve's model: a hole commanded at c is seen at R (c + e(c)) + t in the (unmirrored) bed
// frame, and a job aimed at p through the correction lands where c + e(c) = Rr p + o. A point
// of the view at machine X therefore shows the bed at R (Rr (X - zero) + o) + t, worked here
// from those definitions.
TEST(BedViewFrame, a_view_point_is_where_a_job_aimed_there_lands_in_the_solves_model) {
    for (const bool mirrored : {false, true}) {
        const auto s = hand_result(mirrored);
        const auto map = modes::planar_bed_to_machine(s, "result.json");
        for (const Point2 machine : {Point2{-300, -300}, Point2{-150, -20}, Point2{-12.5, -250}}) {
            const Point2 work{machine.x + 300, machine.y + 300};
            const Point2 aim = turn(work, s.rigid_part.rotation_rad);
            const Point2 moved{aim.x + s.rigid_part.offset_mm.x, aim.y + s.rigid_part.offset_mm.y};
            const Point2 seen = turn(moved, s.fit.rotation_rad);
            Point2 bed{seen.x + s.fit.translation_mm.x, seen.y + s.fit.translation_mm.y};
            if (mirrored) bed.y = -bed.y;
            const Point2 back = map.machine_of(bed);
            DOUBLES_EQUAL(machine.x, back.x, 1e-9);
            DOUBLES_EQUAL(machine.y, back.y, 1e-9);
            const Point2 there = map.bed_of(machine);
            DOUBLES_EQUAL(bed.x, there.x, 1e-9);
            DOUBLES_EQUAL(bed.y, there.y, 1e-9);
        }
    }
}

TEST(BedViewFrame, a_result_that_does_not_say_where_the_bed_lies_gives_no_view) {
    auto s = hand_result(true);
    s.bed_mirrored.reset();
    CHECK_THROWS(modes::BedViewError, modes::planar_bed_to_machine(s, "old.json"));
    try {
        modes::planar_bed_to_machine(s, "old.json");
    } catch (const modes::BedViewError& e) {
        STRCMP_CONTAINS("old.json: a result from before calbox recorded which way round", e.what());
    }
    s = hand_result(true);
    s.frame.reset();
    try {
        modes::planar_bed_to_machine(s, "old.json");
        FAIL("a result without its frame gave a view");
    } catch (const modes::BedViewError& e) {
        STRCMP_CONTAINS("old.json: a result from before calbox recorded the frame", e.what());
    }
}

// The planar result's file keeps which way round the bed lies; one written before it is read
// without it (and gives no view, above).
TEST(BedViewFrame, the_result_file_keeps_the_beds_handedness) {
    auto s = hand_result(true);
    s.fit.residuals_mm.clear();
    const auto text = modes::planar_result_to_json(s, {});
    CHECK(modes::planar_result_from_json(text, "r.json").bed_mirrored == true);
    s.bed_mirrored = false;
    CHECK(modes::planar_result_from_json(modes::planar_result_to_json(s, {}), "r.json")
              .bed_mirrored == false);
    s.bed_mirrored.reset();
    CHECK(!modes::planar_result_from_json(modes::planar_result_to_json(s, {}), "r.json")
               .bed_mirrored.has_value());
}

TEST_GROUP(BedViewRefusals){};

TEST(BedViewRefusals, each_refusal_names_the_figure_that_decided_it) {
    const auto camera = test::as_core(test::router_bench(0.25).camera);  // 1014 x 760
    const auto plane = plane_above();
    const auto s = hand_result(true);
    std::vector<std::uint8_t> pixels(
        static_cast<std::size_t>(camera.image_width) * camera.image_height, 128);
    const vision::GrayView photo{pixels.data(), camera.image_width, camera.image_height,
                                 camera.image_width};
    const auto refused = [&](const modes::BedViewRequest& request, const vision::GrayView& p,
                             const char* expected) {
        try {
            modes::render_bed_view(camera, plane, p, s, request, "result.json");
            FAIL(expected);
        } catch (const modes::BedViewError& e) {
            STRCMP_CONTAINS(expected, e.what());
        }
    };
    modes::BedViewRequest whole;
    // The view at the photo's own scale over the travel: 0.35 mm a pixel there; the photo's
    // 760 rows see 267 mm of the travel's 300 in y.
    const auto view = modes::render_bed_view(camera, plane, photo, s, whole, "result.json");
    DOUBLES_EQUAL(500.0 / camera.fx(), view.camera_mm_per_px, 0.01 * view.camera_mm_per_px);
    DOUBLES_EQUAL(std::ceil(view.camera_mm_per_px * 100) / 100, view.mm_per_px, 1e-12);
    CHECK(view.max_x_mm <= 0 && view.min_y_mm >= -300);
    DOUBLES_EQUAL(760 * 500.0 / camera.fy() / 300, view.seen_share, 0.02);
    const vision::GrayView small{pixels.data(), 640, 480, 640};
    refused(whole, small, "the photo is 640x480, the camera was calibrated at 1014x760");
    modes::BedViewRequest beyond;
    beyond.min_x_mm = -310, beyond.min_y_mm = -300, beyond.max_x_mm = -100, beyond.max_y_mm = 0;
    refused(beyond, photo,
            "the area X -310.000..-100.000 Y -300.000..0.000 mm reaches beyond the machine's "
            "travel (X -300.000..0.000 Y -300.000..0.000 mm)");
    modes::BedViewRequest fine = whole;
    fine.mm_per_px = 0.03;
    refused(fine, photo, "0.030 mm a pixel is under a tenth of the photo's own 0.351 mm");
    fine.mm_per_px = 0.045;
    refused(fine, photo, "pixels, over 40 megapixels: give a coarser scale");
    modes::BedViewRequest flat = whole;
    flat.min_x_mm = -100, flat.max_x_mm = -100, flat.min_y_mm = -200, flat.max_y_mm = -100;
    refused(flat, photo, "has no size");
    // The camera over a point 1.5 m beside the bed.
    auto away = plane;
    away.bed_to_camera.tvec_mm = {-1500, -150, 500};
    try {
        modes::render_bed_view(camera, away, photo, s, whole, "result.json");
        FAIL("a view of what the camera does not see");
    } catch (const modes::BedViewError& e) {
        STRCMP_CONTAINS("the camera sees none of X -300.000..0.000 Y -300.000..0.000 mm", e.what());
    }
}

TEST(BedViewRefusals, the_world_file_places_the_top_left_pixels_centre) {
    const auto camera = test::as_core(test::router_bench(0.25).camera);
    std::vector<std::uint8_t> pixels(
        static_cast<std::size_t>(camera.image_width) * camera.image_height, 128);
    modes::BedViewRequest request;
    request.min_x_mm = -200, request.max_x_mm = -100, request.min_y_mm = -250,
    request.max_y_mm = -150;
    request.mm_per_px = 0.5;
    const auto view = modes::render_bed_view(
        camera, plane_above(),
        {pixels.data(), camera.image_width, camera.image_height, camera.image_width},
        hand_result(true), request, "result.json");
    CHECK_EQUAL(200, view.pixels.width_px);
    CHECK_EQUAL(200, view.pixels.height_px);
    STRCMP_EQUAL("0.5\n0\n0\n-0.5\n-199.75\n-150.25\n", modes::world_file_text(view).c_str());
}

TEST_GROUP(BedViewTwin){};

// A chessboard printed on a 1.5 mm sheet anywhere on the router's bed, turned; the router
// calibrated from its drilled sheet; the view of the printed sheet at its top. Every corner
// OpenCV finds in the view, commanded through the correction, is where the twin's tool really
// goes to within 0.1 mm of the printed corner (the bar).
TEST(BedViewTwin, every_printed_corner_in_the_view_is_where_the_corrected_tool_lands) {
    const auto& router = calibrated_router();
    const auto& bench = router.bench;
    const auto spec = geometry::parse_pattern_spec("chessboard:17x13@15");
    const sim::Vec3 origin{41.5, 237.25, bench.surface_height_mm};
    const double turn_deg = 2.5;
    const auto printed = sim::render_photo(
        bench.camera, sim::compose(bench.bed_to_camera, sim::board_lying_on_bed(origin, turn_deg)),
        sim::BoardScene(spec, 4), bench.photo);
    modes::BedViewRequest request;
    request.surface_height_mm = bench.surface_height_mm;
    request.mm_per_px = 0.2;
    const auto view = modes::render_bed_view(router.camera, router.plane, test::view_of(printed),
                                             router.solution, request, "result.json");
    CHECK_EQUAL(1500, view.pixels.width_px);
    DOUBLES_EQUAL(1.0, view.seen_share, 1e-9);
    const cv::Mat image(view.pixels.height_px, view.pixels.width_px, CV_8UC1,
                        const_cast<std::uint8_t*>(view.pixels.pixels.data()));
    std::vector<cv::Point2f> found;
    CHECK(cv::findChessboardCornersSB(image, cv::Size(17, 13), found, cv::CALIB_CB_ACCURACY));
    CHECK_EQUAL(17u * 13u, found.size());

    // The printed corners where the twin put them, and where its tool goes when a job aimed at
    // a corner's view position is commanded through the correction (drilling as the target
    // drills: to the cut depth, approached from -x -y).
    const double a = turn_deg * kPi / 180;
    std::vector<sim::Vec2> corners;
    for (int j = 0; j < 13; ++j)
        for (int i = 0; i < 17; ++i)
            corners.push_back({origin.x + 15 * (i * std::cos(a) + j * std::sin(a)),
                               origin.y + 15 * (i * std::sin(a) - j * std::cos(a))});
    std::vector<bool> taken(corners.size(), false);
    double sum = 0, sum2 = 0, worst = 0;
    for (const auto& f : found) {
        const sim::Vec2 tool = router.lands(view.machine_of_pixel(f.x, f.y));
        std::size_t nearest = 0;
        double d = 1e300;
        for (std::size_t k = 0; k < corners.size(); ++k) {
            const double e = std::hypot(tool.x - corners[k].x, tool.y - corners[k].y);
            if (e < d) d = e, nearest = k;
        }
        CHECK(!taken[nearest]);
        taken[nearest] = true;
        sum += d;
        sum2 += d * d;
        worst = std::max(worst, d);
    }
    const double n = static_cast<double>(found.size());
    UT_PRINT(("bed view at 0.2 mm/px (the photo's " + std::to_string(view.camera_mm_per_px) +
              "): 221 corners, the corrected tool from the printed corner " +
              std::to_string(sum / n) + " mm mean, " + std::to_string(std::sqrt(sum2 / n)) +
              " RMS, " + std::to_string(worst) + " worst; stated +/-" +
              std::to_string(view.accuracy_mm) + " mm (2 sigma)")
                 .c_str());
    CHECK(worst < 0.1);
    CHECK(sum / n < 0.05);
    // The stated accuracy is honest: two standard deviations per coordinate cover the RMS of
    // the distance (which is sqrt(2) sigma), and it is under the bar.
    CHECK(std::sqrt(sum2 / n) <= view.accuracy_mm);
    CHECK(view.accuracy_mm < 0.1);
}

// A printer's job is in machine coordinates: a place from the camera is refused, not ignored.
TEST(BedViewFrame, a_printers_job_takes_no_place_from_the_camera) {
    auto s = hand_result(true);
    s.fit.residuals_mm.clear();
    s.frame->firmware = "marlin";
    s.frame->kind = "cartesian";
    modes::JobRequest request;
    request.result_text = modes::planar_result_to_json(s, {});
    request.result_name = "result.json";
    request.job_text = "G28\nG1 X10 Y10 F600\n";
    request.job_name = "part.gcode";
    request.registration_text = modes::registration_to_json(modes::Registration{}, "");
    request.registration_name = "marks.json";
    request.date = "2026-11-29";
    try {
        modes::compensate_job(request);
        FAIL("a printer's job was placed by marks");
    } catch (const modes::JobError& e) {
        STRCMP_CONTAINS(
            "part.gcode: a printer's job is in machine coordinates (its G92 tracked); "
            "--work-zero, --stock and --register are for routers and lasers",
            e.what());
    }
}
