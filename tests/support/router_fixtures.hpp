#pragma once
// The router's bench on the twin: the machine file, a 12 MP camera over its 300 x 300 mm work
// area, a sheet drilled on a twin router over a dark backing and photographed, the bed plane
// from a board lying on the spoilboard.
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "board/sim/router_twin.hpp"
#include "core/geometry/calibration.hpp"
#include "core/models/machine_file.hpp"
#include "tests/support/surroundings.hpp"
#include "tests/support/twin_fixtures.hpp"

namespace calbox::test {

// A 300 x 300 mm router drilling 1/8" holes at 25 mm through a 1.5 mm sheet.
inline constexpr const char* kRouterMachineToml = R"toml(
[machine]
kind = "router"
firmware = "grbl"
bed_size_x_mm = 300.0
bed_size_y_mm = 300.0
tool_width_mm = 3.175
cut_depth_mm = 2.0
safe_height_mm = 5.0
feed_mm_s = 10.0
travel_feed_mm_s = 80.0
spindle_rpm = 12000
[planar]
hole_pitch_mm = 25.0
margin_mm = 12.5
surface_height_mm = 1.5
tool_length_mm = 80.0
)toml";

struct RouterBench {
    sim::CameraIntrinsics camera;
    sim::Pose bed_to_camera;
    sim::PhotoSettings photo;
    double surface_height_mm = 1.5;
};

// The HQ-class camera 620 mm above the middle of the work area, turned a little: the whole
// 300 x 300 mm area in its 3040-pixel height, 0.11 mm a pixel. `scale` shrinks it for tests
// that need fewer pixels.
inline RouterBench router_bench(double scale = 1.0) {
    RouterBench b;
    b.camera = hq_camera();
    b.camera.width_px = static_cast<int>(std::lround(b.camera.width_px * scale));
    b.camera.height_px = static_cast<int>(std::lround(b.camera.height_px * scale));
    b.camera.fx *= scale, b.camera.fy *= scale;
    b.camera.cx = (b.camera.cx + 0.5) * scale - 0.5;
    b.camera.cy = (b.camera.cy + 0.5) * scale - 0.5;
    b.bed_to_camera = sim::look_at_pose({154, 147, 620}, {150, 150, 0}, 3);
    b.photo.blur_sigma_px = 0.8;
    b.photo.noise_sigma_dn = 2;
    return b;
}

// What goes wrong at a drilled hole: burrs (a sliver of the sheet's edge torn into the hole or
// out of it), and chips fused to a hole's edge.
struct DrillFaults {
    int burrs_per_hole = 3;
    double burr_radius_mm = 0.08;
    std::vector<std::size_t> chipped_holes;  // by the order the job drills them
    double chip_radius_mm = 0.6;
    unsigned seed = 1;
};

// The sheet drilled by `job` on `truth`, as the camera sees it: a light sheet, the dark backing
// through the holes.
inline sim::GrayImage photo_of_drilled_sheet(const RouterBench& bench,
                                             const sim::RouterTruth& truth, const std::string& job,
                                             const DrillFaults& faults = {},
                                             const std::optional<WorkOnBed>& sheet = {}) {
    sim::RouterTwin twin(truth);
    sim::ToolSettings tool;
    tool.kind = sim::ToolKind::spindle;
    tool.tool_width_mm = 3.175;
    sim::GcodeRunner runner(twin, tool);
    std::istringstream in(job);
    runner.run(in);
    auto strokes = sim::holes_on_the_sheet(runner.result().strokes, bench.surface_height_mm);
    sim::RouterTwin again(truth);
    const auto centres = sim::drilled_hole_centres_mm(again, job);
    std::mt19937 random(faults.seed);
    std::uniform_real_distribution<double> angle(0, 2 * 3.14159265358979);
    const double rim = 0.5 * tool.tool_width_mm;
    for (std::size_t h = 0; h < centres.size(); ++h) {
        for (int k = 0; k < faults.burrs_per_hole; ++k) {
            const double a = angle(random);
            const sim::Vec3 at{centres[h].x + rim * std::cos(a), centres[h].y + rim * std::sin(a),
                               bench.surface_height_mm};
            strokes.push_back({at, at, 2 * faults.burr_radius_mm});
        }
        for (std::size_t c : faults.chipped_holes)
            if (c == h) {
                const double r = rim + 0.8 * faults.chip_radius_mm;
                const sim::Vec3 at{centres[h].x + r, centres[h].y + 0.3 * r,
                                   bench.surface_height_mm};
                strokes.push_back({at, at, 2 * faults.chip_radius_mm});
            }
    }
    const sim::StrokeScene drilled(std::move(strokes), 0.82, 0.1, 4,
                                   2 * bench.bed_to_camera.translation_mm.z / bench.camera.fx);
    if (sheet)
        return sim::render_photo(bench.camera, bench.bed_to_camera,
                                 SurroundedScene(drilled, *sheet), bench.photo);
    return sim::render_photo(bench.camera, bench.bed_to_camera, drilled, bench.photo);
}

// A camera the router carries on its gantry, 380 mm above the sheet: the half-size HQ camera
// sees 270 x 203 mm, so four views cover the work area with room to overlap. Sent to `view_mm`,
// it goes where the machine really takes its carriage (its errors included) and turns with the
// gantry's yaw.
inline sim::Pose carried_camera_pose(const sim::RouterTruth& truth, sim::Vec2 view_mm) {
    const sim::Vec3 at =
        sim::router_tool_position_mm(truth, {view_mm.x, view_mm.y, 0}, {true, true});
    const double yaw_deg = truth.gantry_yaw_rad_per_mm * view_mm.y * 180 / 3.14159265358979;
    return sim::look_at_pose({at.x + 4, at.y - 3, 380}, {at.x + 4, at.y - 3 + 1e-3, 0},
                             3 + yaw_deg);
}

// The bed plane from a 15 x 11 chessboard of 15 mm squares lying on the spoilboard (its rows
// run towards -y).
inline geometry::BedPlane router_plane(const RouterBench& bench) {
    return plane_from_board(bench.camera, bench.bed_to_camera,
                            {"chessboard:15x11@15", {45, 235, 0}}, bench.photo);
}

}  // namespace calbox::test
