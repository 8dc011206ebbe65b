#pragma once
// The galvo scanner's bench on the twin: the machine file, the seed paper's camera over a
// 110 mm field, a grid burned on a twin scanner and photographed, the bed plane from a board.
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "board/sim/galvo_twin.hpp"
#include "core/geometry/calibration.hpp"
#include "core/models/machine_file.hpp"
#include "core/targets/galvo_target.hpp"
#include "tests/support/surroundings.hpp"
#include "tests/support/twin_fixtures.hpp"

namespace calbox::test {

// A 110 mm field, a 0.1 mm spot, marks on a glass disc 2 mm above the platform.
inline constexpr const char* kGalvoMachineToml = R"toml(
[machine]
kind = "galvo"
firmware = "grbl"
tool_width_mm = 0.1
feed_mm_s = 500.0
travel_feed_mm_s = 2000.0
[galvo]
field_size_mm = 110.0
substrate_height_mm = 2.0
)toml";

// The seed paper's Daheng MER2-2000 (5496 x 3672, 2.4 um pixels) behind a 26 mm lens: the whole
// 110 mm field in the frame's height from 350 mm, 0.032 mm a pixel. `scale` shrinks it for the
// tests that need fewer pixels.
inline sim::CameraIntrinsics galvo_camera(double scale = 1.0) {
    sim::CameraIntrinsics c;
    c.width_px = static_cast<int>(std::lround(5496 * scale));
    c.height_px = static_cast<int>(std::lround(3672 * scale));
    c.fx = c.fy = 10900 * scale;
    c.cx = (c.width_px - 1) / 2.0 + 6.3 * scale;
    c.cy = (c.height_px - 1) / 2.0 - 4.1 * scale;
    c.distortion = {-0.04, 0.06, 0.0001, -0.0002, 0};
    return c;
}

struct GalvoBench {
    sim::CameraIntrinsics camera;
    sim::Pose bed_to_camera;
    sim::PhotoSettings photo;
    bool dark_marks = true;  // dark marks on a light substrate, or light on dark
};

// The grid burned on `truth` (with `faults`), as the box's camera sees it.
inline sim::GrayImage photo_of_burned_grid(const GalvoBench& bench, const sim::GalvoTruth& truth,
                                           const std::string& job,
                                           const sim::BurnFaults& faults = {},
                                           const std::optional<WorkOnBed>& plate = {}) {
    sim::GalvoTwin twin(truth);
    sim::ToolSettings tool;
    tool.kind = sim::ToolKind::laser;
    tool.tool_width_mm = 0.1;
    sim::GcodeRunner runner(twin, tool);
    std::istringstream in(job);
    runner.run(in);
    const double substrate = bench.dark_marks ? 0.85 : 0.08, mark = bench.dark_marks ? 0.12 : 0.8;
    const sim::StrokeScene burned(sim::with_burn_faults(runner.result().strokes, faults), substrate,
                                  mark, 4,
                                  2 * bench.bed_to_camera.translation_mm.z / bench.camera.fx);
    if (plate)
        return sim::render_photo(bench.camera, bench.bed_to_camera, SurroundedScene(burned, *plate),
                                 bench.photo);
    return sim::render_photo(bench.camera, bench.bed_to_camera, burned, bench.photo);
}

// The bed plane from a 15 x 11 chessboard of 8 mm squares lying on the platform.
inline geometry::BedPlane plane_from_board(const GalvoBench& bench) {
    return plane_from_board(bench.camera, bench.bed_to_camera, {"chessboard:15x11@8", {-56, 40, 0}},
                            bench.photo);
}

}  // namespace calbox::test
