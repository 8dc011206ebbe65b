// The delta target: deterministic, quick to print, and what the twin prints of it is what the
// box can see.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <sstream>

#include "board/sim/camera_reference.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenes.hpp"
#include "core/models/machine_file.hpp"
#include "core/targets/delta_target.hpp"
#include "core/vision/markers.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;

namespace {}  // namespace

TEST_GROUP(DeltaTarget){};

TEST(DeltaTarget, is_deterministic_spread_over_the_bed_and_prints_in_under_ten_minutes) {
    const auto machine = models::parse_machine_file(test::kDeltaMachineToml, "test");
    const auto a = targets::make_delta_target(machine), b = targets::make_delta_target(machine);
    CHECK_EQUAL(jobs::write_gcode(a.job, machine, "t"), jobs::write_gcode(b.job, machine, "t"));
    STRCMP_EQUAL(a.fingerprint.c_str(), b.fingerprint.c_str());
    // Each marker ringed by its own strand, with room for a pressed strand's spread: nine on an
    // 85 mm bed, 36 ring corners.
    CHECK(a.markers.size() >= 9);
    for (const auto& m : a.markers) DOUBLES_EQUAL(8 + 1.5 + 0.225, m.outline_half_mm, 1e-12);
    CHECK_EQUAL(3u, a.bars.size());
    double reach = 0;
    for (const auto& m : a.markers)
        for (const auto& c : m.outline_corners_mm) reach = std::max(reach, std::hypot(c.x, c.y));
    CHECK(reach > 55);  // features reach well out towards the edge of the 85 mm bed
    CHECK(a.job.estimated_time_s(machine) < 600);
}

TEST(DeltaTarget, the_twin_prints_it_and_every_marker_is_seen_where_it_was_commanded) {
    const auto machine = models::parse_machine_file(test::kDeltaMachineToml, "test");
    const auto target = targets::make_delta_target(machine);
    sim::DeltaParams exact;
    sim::DeltaTwin twin(exact, exact);
    auto strokes = test::print_on_twin(twin, jobs::write_gcode(target.job, machine, "target"));
    const sim::CameraIntrinsics camera = test::hq_camera();
    const sim::Pose pose = sim::look_at_pose({0, -35, 400}, {0, 0, 0}, 0);
    sim::PhotoSettings photo;
    photo.blur_sigma_px = 0.7;
    photo.noise_sigma_dn = 2.0;
    const auto image = test::photo_of_print(camera, pose, std::move(strokes), photo);
    vision::MarkerOptions options;
    const auto found = vision::detect_markers(
        {image.pixels.data(), image.width_px, image.height_px, image.width_px}, options);
    CHECK_EQUAL(target.markers.size(), found.size());
    double worst = 0;
    for (const auto& m : found) {
        CHECK(m.id >= 0 && m.id < static_cast<int>(target.markers.size()));
        for (int k = 0; k < 4; ++k) {
            const auto& c = target.markers[static_cast<std::size_t>(m.id)]
                                .corners_mm[static_cast<std::size_t>(k)];
            const auto truth = sim::project_point(camera, pose, {c.x, c.y, target.top_height_mm});
            const double e = std::hypot(m.corners[static_cast<std::size_t>(k)].x - truth.x,
                                        m.corners[static_cast<std::size_t>(k)].y - truth.y);
            worst = std::max(worst, e);
        }
    }
    UT_PRINT(("printed marker corners: worst " + std::to_string(worst) +
              " px from their commanded place")
                 .c_str());
    // Printed corners are not rendered ones (filled cells, noise, blur); still within 0.15 px
    // (0.01 mm) of where they were commanded.
    CHECK_TEXT(worst < 0.15, ("worst printed corner " + std::to_string(worst) + " px").c_str());
}
