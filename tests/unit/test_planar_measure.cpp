// The measurement of a drilled sheet: holes found and fitted, refusals named, and the cycle's
// figures on twin routers against their hidden truth.
#include "tests/unit/planar_rig.hpp"

TEST_GROUP(PlanarMeasure){};

TEST(PlanarMeasure, every_hole_is_found_where_the_twin_drilled_it) {
    const auto machine = router_machine();
    const auto target = targets::make_planar_target(machine);
    const auto bench = test::router_bench(0.5);
    const auto camera = test::as_core(bench.camera);
    const auto plane = test::router_plane(bench);
    const auto truth = sim::random_router_truth(4);
    test::DrillFaults faults;
    faults.chipped_holes = {40};
    const auto photo = test::photo_of_drilled_sheet(bench, truth, target.job, faults);
    const auto m = modes::measure_planar(machine, camera, plane, test::view_of(photo));
    CHECK(!m.mirrored);
    // The chipped hole is reported, not measured.
    CHECK_EQUAL(142u, m.holes.size());
    CHECK_EQUAL(1u, m.missing.size());
    CHECK(m.missing[0] == target.holes[40].index);
    CHECK(!m.extra_mm.empty());
    const auto truly = drilled(truth, target.job);
    std::vector<Point2> seen, real;
    // The large holes are widened by a circle, which the drives' backlash bends: their centres
    // are where the two fiducials are, not where the tool plunged; they are left out of the fit.
    for (const auto& hole : m.holes)
        for (std::size_t i = 0; i < target.holes.size(); ++i)
            if (target.holes[i].index == hole.index && !hole.large) {
                seen.push_back(hole.measured_mm);
                real.push_back(truly[i]);
            }
    const auto placement = geometry::best_rigid_placement(seen, real);
    double worst = 0, sum = 0;
    for (std::size_t i = 0; i < seen.size(); ++i) {
        const Point2 p = placement.apply(seen[i]);
        const double e = std::hypot(p.x - real[i].x, p.y - real[i].y);
        worst = std::max(worst, e);
        sum += e;
    }
    UT_PRINT(("holes against the twin: mean " + std::to_string(sum / seen.size()) + " worst " +
              std::to_string(worst) + " mm")
                 .c_str());
    // Half the camera's 12 MP (0.21 mm a pixel, holes 15 pixels across), burrs on every hole.
    CHECK(sum / static_cast<double>(seen.size()) < 0.015);
    CHECK(worst < 0.05);
}

namespace {

// The message a measurement refuses with, or "" when it does not.
std::string refusal(const models::MachineFile& machine, const sim::GrayImage& photo,
                    const test::RouterBench& bench) {
    const auto camera = test::as_core(bench.camera);
    const auto plane = test::router_plane(bench);
    try {
        modes::measure_planar(machine, camera, plane, test::view_of(photo));
    } catch (const modes::PlanarError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

// The case: the drilled sheet filling part of the frame, the machine's bed around it
// dark (half the frame below Otsu's level: no hole was found), grey or white.
TEST(PlanarMeasure, a_sheet_amid_a_dark_grey_or_white_bed_gives_every_hole) {
    const auto machine = router_machine();
    const auto target = targets::make_planar_target(machine);
    const auto bench = test::router_bench(0.5);
    const auto camera = test::as_core(bench.camera);
    const auto plane = test::router_plane(bench);
    const auto truth = sim::random_router_truth(5);
    for (const double bed : {0.04, 0.5, 0.97}) {
        const auto photo = test::photo_of_drilled_sheet(bench, truth, target.job, {},
                                                        test::WorkOnBed{-2, -2, 302, 302, bed});
        const auto m = modes::measure_planar(machine, camera, plane, test::view_of(photo));
        UT_PRINT(("bed " + std::to_string(bed) + ": " + std::to_string(m.holes.size()) +
                  " holes, " + std::to_string(m.missing.size()) + " missing")
                     .c_str());
        CHECK_EQUAL(target.holes.size(), m.holes.size());
        CHECK(m.missing.empty());
    }
}

TEST(PlanarMeasure, a_holes_centroid_under_perspective_and_the_lens_is_its_centre_within_2_um) {
    // A hole's outline is a circle on the sheet; seen at an angle and through the lens its image
    // is no longer centred on the centre's image. At the chosen size (a 3.175 mm bit) and the
    // bench's geometry (620 mm up, the work area's corners 20 degrees off the axis) that bias is
    // shown below 0.002 mm, so it is not corrected. Full resolution, no noise, one hole at a time.
    const auto bench = test::router_bench(1.0);
    const auto camera = test::as_core(bench.camera);
    // The plane as the twin has it: what is tested here is the centroid, not the board.
    geometry::BedPlane plane;
    const sim::Vec3 r = sim::vector_from_rotation(bench.bed_to_camera.rotation);
    plane.bed_to_camera.rvec = {r.x, r.y, r.z};
    plane.bed_to_camera.tvec_mm = {bench.bed_to_camera.translation_mm.x,
                                   bench.bed_to_camera.translation_mm.y,
                                   bench.bed_to_camera.translation_mm.z};
    double worst = 0;
    for (const Point2 at : {Point2{12.5, 12.5}, Point2{287.5, 12.5}, Point2{287.5, 287.5},
                            Point2{12.5, 287.5}, Point2{150, 150}}) {
        const sim::Vec3 c{at.x, at.y, bench.surface_height_mm};
        auto photo_settings = bench.photo;
        photo_settings.noise_sigma_dn = 0;
        const auto photo =
            sim::render_photo(bench.camera, bench.bed_to_camera,
                              sim::StrokeScene({{c, c, 3.175}}, 0.82, 0.1, 8, 0.3), photo_settings);
        const auto spots = vision::find_spots(test::view_of(photo));
        CHECK_EQUAL(1u, spots.spots.size());
        const auto on_bed = geometry::pixels_to_bed(camera, plane, {spots.spots[0].centre_px},
                                                    bench.surface_height_mm);
        const double e = std::hypot(on_bed[0].x - at.x, on_bed[0].y - at.y);
        worst = std::max(worst, e);
    }
    UT_PRINT(("a hole's centroid against its centre: worst " + std::to_string(worst * 1000) + " um")
                 .c_str());
    CHECK(worst < 0.002);
}

TEST(PlanarMeasure, a_duplicate_grid_another_pitch_or_a_cut_off_photo_is_refused_in_one_line) {
    const auto machine = router_machine();
    const auto target = targets::make_planar_target(machine);
    const auto bench = test::router_bench(0.5);
    const sim::RouterTruth exact;
    // The sheet drilled twice, the second time 8 mm off: two holes where the grid has one.
    std::string twice = target.job;
    for (const auto& hole : target.holes) {
        targets::PlanarHole moved = hole;
        moved.centre_mm.x += 8;
        twice += targets::write_drilling_job(machine, {moved}, target.hole_diameter_mm,
                                             target.large_diameter_mm, "again");
    }
    const std::string duplicate =
        refusal(machine, test::photo_of_drilled_sheet(bench, exact, twice), bench);
    UT_PRINT(duplicate.c_str());
    CHECK(duplicate.find("pairs of large holes") != std::string::npos ||
          duplicate.find("two holes where the grid has one") != std::string::npos);
    // A sheet drilled at 20 mm pitch, measured as the 25 mm one.
    auto other = machine;
    other.planar->hole_pitch_mm = 20;
    const std::string pitch = refusal(
        machine, test::photo_of_drilled_sheet(bench, exact, targets::make_planar_target(other).job),
        bench);
    UT_PRINT(pitch.c_str());
    CHECK(pitch.find("not this target") != std::string::npos);
    // Half the sheet outside the photo: drilled 160 mm further along x on a longer machine.
    std::vector<targets::PlanarHole> shifted = target.holes;
    for (auto& h : shifted) h.centre_mm.x += 160;
    sim::RouterTruth longer;
    longer.travel_x_mm = 600;
    const std::string cut =
        refusal(machine,
                test::photo_of_drilled_sheet(
                    bench, longer,
                    targets::write_drilling_job(machine, shifted, target.hole_diameter_mm,
                                                target.large_diameter_mm, "shifted")),
                bench);
    UT_PRINT(cut.c_str());
    CHECK(cut.find("outside the photo") != std::string::npos);
    CHECK(!cut.empty());
    CHECK(cut.find('\n') == std::string::npos);
}

TEST(PlanarMeasure, a_hole_not_drilled_and_swarf_on_the_sheet_are_listed_not_fatal) {
    const auto machine = router_machine();
    auto target = targets::make_planar_target(machine);
    const auto bench = test::router_bench(0.5);
    const auto camera = test::as_core(bench.camera);
    const auto plane = test::router_plane(bench);
    // Hole (5, 6) never drilled: the job without it.
    std::vector<targets::PlanarHole> holes;
    for (const auto& h : target.holes)
        if (!(h.index == targets::GridIndex{5, 6})) holes.push_back(h);
    std::string job = targets::write_drilling_job(machine, holes, target.hole_diameter_mm,
                                                  target.large_diameter_mm, "one short");
    // A chip of the backing's colour between holes: a stray plunge of a smaller tool.
    auto small_tool = machine;
    small_tool.tool_width_mm = 1.0;
    job +=
        targets::write_drilling_job(small_tool, {{{0, 0}, {100, 112.5}, false}}, 1.0, 2.0, "swarf");
    const auto photo = test::photo_of_drilled_sheet(bench, sim::RouterTruth{}, job);
    const auto m = modes::measure_planar(machine, camera, plane, test::view_of(photo));
    CHECK_EQUAL(142u, m.holes.size());
    CHECK_EQUAL(1u, m.missing.size());
    CHECK(m.missing[0] == (targets::GridIndex{5, 6}));
    CHECK_EQUAL(1u, m.extra_mm.size());
}

TEST(PlanarMeasure,
     four_overlapping_photos_from_a_camera_on_the_gantry_are_stitched_through_shared_holes) {
    const auto machine = router_machine();
    const auto target = targets::make_planar_target(machine);
    const auto truth = sim::random_router_truth(5);
    auto bench = test::router_bench(0.5);
    const std::vector<sim::Vec2> sent{{90, 90}, {210, 90}, {90, 210}, {210, 210}};
    // The camera calibrated and the plane laid down under the first view.
    bench.bed_to_camera = test::carried_camera_pose(truth, sent[0]);
    const auto camera = test::as_core(bench.camera);
    const auto plane = test::plane_from_board(bench.camera, bench.bed_to_camera,
                                              {"chessboard:15x11@10", {20, 150, 0}}, bench.photo);
    std::vector<sim::GrayImage> photos;
    for (const auto& v : sent) {
        auto at = bench;
        at.bed_to_camera = test::carried_camera_pose(truth, v);
        photos.push_back(test::photo_of_drilled_sheet(at, truth, target.job));
    }
    std::vector<modes::PlanarView> views;
    for (std::size_t i = 0; i < photos.size(); ++i)
        views.push_back({test::view_of(photos[i]), {sent[i].x, sent[i].y}});
    const auto m = modes::measure_planar_views(machine, camera, plane, views);
    CHECK_EQUAL(143u, m.holes.size());
    // Against where the twin drilled them: the stitching keeps the holes where they are, not
    // where the camera was sent (which is off by the machine's own errors, millimetres).
    const auto truly = drilled(truth, target.job);
    std::vector<Point2> seen, real;
    for (const auto& hole : m.holes)
        for (std::size_t i = 0; i < target.holes.size(); ++i)
            if (target.holes[i].index == hole.index && !hole.large) {
                seen.push_back(hole.measured_mm);
                real.push_back(truly[i]);
            }
    const auto placement = geometry::best_rigid_placement(seen, real);
    double worst = 0, sum = 0;
    for (std::size_t i = 0; i < seen.size(); ++i) {
        const Point2 p = placement.apply(seen[i]);
        const double e = std::hypot(p.x - real[i].x, p.y - real[i].y);
        worst = std::max(worst, e);
        sum += e;
    }
    UT_PRINT(("four photos stitched, holes against the twin: mean " +
              std::to_string(sum / seen.size()) + " worst " + std::to_string(worst) + " mm")
                 .c_str());
    CHECK(sum / static_cast<double>(seen.size()) < 0.006);
    CHECK(worst < 0.015);
    // Stitched through the camera's pose alone (where it was sent), the holes would be off by
    // the machine's errors at the camera: what the shared holes take out.
    const auto solution = modes::solve_planar(machine, m);
    const jobs::Correction correct = [&](Point2 p) {
        return modes::planar_command_for(solution, p);
    };
    const auto verdict = sim::judge_router_fresh_holes(truth, machine, &correct);
    UT_PRINT(("four photos: fresh holes " + std::to_string(verdict.before.mean_mm) + " -> " +
              std::to_string(verdict.after->mean_mm) + " mm mean")
                 .c_str());
    CHECK(verdict.after->mean_mm < 0.05);
}
