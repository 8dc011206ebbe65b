// core/vision judged on twin-rendered images, against the twin's truth.
#include "tests/unit/vision_scenes.hpp"

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
