#pragma once
// What the bed view's tests (test_bed_view*.cpp) share: a hand-worked planar result, the bed plane,
// and a twin router calibrated from its photos.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "board/sim/scenes.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "core/modes/bed_view.hpp"
#include "core/modes/compensate_job.hpp"
#include "core/modes/planar.hpp"
#include "core/modes/registration.hpp"
#include "core/modes/stock.hpp"
#include "core/targets/planar_target.hpp"
#include "tests/support/router_fixtures.hpp"

using namespace calbox;
using geometry::Point2;

namespace bed_view_rig {

inline constexpr double kPi = 3.14159265358979323846;

// A result as a solve writes it, its figures chosen by hand: the machine's frame turned 0.6
// degrees in the camera's and shifted, a rigid part left out, G54 at machine -300, -300.
inline modes::PlanarSolution hand_result(bool mirrored) {
    modes::PlanarSolution s;
    s.fit.rotation_rad = 0.0105;
    s.fit.translation_mm = {5.25, -3.5};
    s.rigid_part.rotation_rad = 0.0012;
    s.rigid_part.offset_mm = {0.2, -0.15};
    s.fit.residual_rms_mm = 0.004;
    s.bed_mirrored = mirrored;
    modes::PlanarFrame f;
    f.work_zero_mm = {-300, -300};
    f.travel_min_x_mm = -300, f.travel_min_y_mm = -300, f.travel_max_x_mm = 0,
    f.travel_max_y_mm = 0;
    s.frame = f;
    s.min_x_mm = 12.5, s.min_y_mm = 12.5, s.max_x_mm = 287.5, s.max_y_mm = 287.5;
    return s;
}

inline Point2 turn(Point2 p, double a) {
    return {std::cos(a) * p.x - std::sin(a) * p.y, std::sin(a) * p.x + std::cos(a) * p.y};
}

// A camera 500 mm straight above the middle of the router's work area (the bed frame's y
// mirrored against the machine's, as a board whose rows run towards -y gives it).
inline geometry::BedPlane plane_above() {
    geometry::BedPlane plane;
    plane.bed_to_camera.rvec = {kPi, 0, 0};  // bed (x, y, z) -> camera (x, -y, -z)
    plane.bed_to_camera.tvec_mm = {-150, -150, 500};
    plane.rms_px = 0.1;
    return plane;
}

}  // namespace bed_view_rig

namespace bed_view_rig {

// A router calibrated from its drilled sheet on the twin (half the 12 MP camera over it): what
// the box keeps after a cycle, and the twin's truth for the judge. Made once for the tests below.
struct CalibratedRouter {
    models::MachineFile machine =
        models::parse_machine_file(test::kRouterMachineToml, "router.toml");
    test::RouterBench bench = test::router_bench(0.5);
    geometry::CameraModel camera = test::as_core(bench.camera);
    geometry::BedPlane plane = test::router_plane(bench);
    sim::RouterTruth truth = sim::random_router_truth(3);
    modes::PlanarSolution solution;
    CalibratedRouter() {
        const auto target = targets::make_planar_target(machine);
        const auto drilled = test::photo_of_drilled_sheet(bench, truth, target.job);
        solution = modes::solve_planar(
            machine, modes::measure_planar(machine, camera, plane, test::view_of(drilled)));
    }
    // The camera's pose against a surface `top_mm` above the bed (a sheet's or a card's top).
    sim::Pose pose_over(double top_mm) const {
        sim::Pose lifted;
        lifted.translation_mm = {0, 0, top_mm};
        return sim::compose(bench.bed_to_camera, lifted);
    }
    // Where the twin's tool really goes for a job aimed at `machine_mm` through the correction
    // (drilling as the target drills: to the cut depth, approached from -x -y).
    sim::Vec2 lands(Point2 machine_mm) const {
        const Point2 zero = solution.frame->work_zero_mm;
        const Point2 command =
            modes::planar_command_for(solution, {machine_mm.x - zero.x, machine_mm.y - zero.y});
        const sim::Vec3 tool = sim::router_tool_position_mm(
            truth, {command.x, command.y, -machine.cut_depth_mm}, {true, true});
        return {tool.x, tool.y};
    }
    // The machine coordinates a job through the correction must aim at to land on `bed`.
    Point2 aim_for(sim::Vec2 bed) const {
        const Point2 zero = solution.frame->work_zero_mm;
        Point2 x{bed.x + zero.x, bed.y + zero.y};
        for (int k = 0; k < 20; ++k) {
            const sim::Vec2 t = lands(x);
            x = {x.x + bed.x - t.x, x.y + bed.y - t.y};
        }
        return x;
    }
};

inline const CalibratedRouter& calibrated_router() {
    static const CalibratedRouter router;
    return router;
}

}  // namespace bed_view_rig

using namespace bed_view_rig;
