#pragma once
// Small pieces the tests share: the box's 12 MP camera, views of rendered images, the core
// camera model of a twin camera, the bed plane from a board lying on the bed.
#include <sstream>
#include <string>
#include <vector>

#include "board/sim/camera_reference.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/scenes.hpp"
#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/image_view.hpp"

namespace calbox::test {

// The delta printer most tests use: 85 mm bed, 0.45 mm line, Marlin's 250 / 140 geometry.
inline constexpr const char* kDeltaMachineToml = R"toml(
[machine]
kind = "delta"
bed_radius_mm = 85.0
line_width_mm = 0.45
layer_height_mm = 0.2
filament_diameter_mm = 1.75
feed_mm_s = 30.0
travel_feed_mm_s = 120.0
[delta]
diagonal_rod_mm = 250.0
radius_mm = 140.0
)toml";

// The replies a twin gives to a job's lines (a probe job's reports), in order.
inline std::vector<std::string> replies_of_twin(sim::MachineTwin& twin,
                                                const std::vector<std::string>& lines) {
    sim::GcodeRunner runner(twin, sim::ToolSettings{});
    for (const auto& line : lines) runner.run_line(line);
    return runner.result().replies;
}

// Runs a whole G-code job on a twin and returns the material it left, ready to render.
inline std::vector<sim::StrokeSegment> print_on_twin(sim::MachineTwin& twin,
                                                     const std::string& gcode) {
    sim::GcodeRunner runner(twin, sim::ToolSettings{});
    std::istringstream job(gcode);
    runner.run(job);
    std::vector<sim::StrokeSegment> strokes;
    strokes.reserve(runner.result().strokes.size());
    for (const auto& s : runner.result().strokes) strokes.push_back(sim::material_of(s));
    return strokes;
}

// A Raspberry Pi HQ-class 4056x3040 camera: 0.07 mm/px at 400 mm, a mild lens.
inline sim::CameraIntrinsics hq_camera() {
    sim::CameraIntrinsics c;
    c.width_px = 4056;
    c.height_px = 3040;
    c.fx = c.fy = 5700;
    c.cx = 2030.1;
    c.cy = 1517.6;
    c.distortion = {-0.05, 0.08, 0.0002, -0.0001, 0};
    return c;
}

// What the box's camera sees of printed material on the scenario's default bed and filament
// (matte black PEI, white PETG), edges sampled 4x4 per pixel.
inline sim::GrayImage photo_of_print(const sim::CameraIntrinsics& camera, const sim::Pose& pose,
                                     std::vector<sim::StrokeSegment> strokes,
                                     const sim::PhotoSettings& photo) {
    const sim::Scenario defaults;
    return sim::render_photo(
        camera, pose,
        sim::StrokeScene(std::move(strokes), defaults.bed_albedo, defaults.material_albedo, 4,
                         sim::stroke_footprint_mm(camera, pose.translation_mm.norm())),
        photo);
}

// The same on another bed and filament, with the bed's grain and the filament's gloss.
inline sim::GrayImage photo_of_print(const sim::CameraIntrinsics& camera, const sim::Pose& pose,
                                     std::vector<sim::StrokeSegment> strokes,
                                     const sim::PhotoSettings& photo, double bed_albedo,
                                     double material_albedo, const sim::StrokeSurface& surface) {
    return sim::render_photo(
        camera, pose,
        sim::StrokeScene(std::move(strokes), bed_albedo, material_albedo, 4,
                         sim::stroke_footprint_mm(camera, pose.translation_mm.norm()), surface),
        photo);
}

inline vision::GrayView view_of(const sim::GrayImage& image) {
    return {image.pixels.data(), image.width_px, image.height_px, image.width_px};
}

inline geometry::CameraModel as_core(const sim::CameraIntrinsics& c) {
    return sim::as_camera_model(c);
}

// The bed plane as the box takes it: a chessboard (`pattern`, the calbox form) lying on the bed,
// its first inner corner at `corner_mm` (z: the bed's height under it), turned `turn_deg`, `thick`
// mm thick, photographed by `camera` at `bed_to_camera`, and the plane estimated from the photo.
struct BoardOnBed {
    std::string pattern = "chessboard:9x6@20";
    sim::Vec3 corner_mm{-80, 50, 0};
    double turn_deg = 0;
    double thickness_mm = 0;
};
inline geometry::BedPlane plane_from_board(const sim::CameraIntrinsics& camera,
                                           const sim::Pose& bed_to_camera, const BoardOnBed& board,
                                           const sim::PhotoSettings& photo) {
    const auto spec = geometry::parse_pattern_spec(board.pattern);
    const auto image = sim::render_photo(
        camera,
        sim::compose(bed_to_camera,
                     sim::board_lying_on_bed(board.corner_mm + sim::Vec3{0, 0, board.thickness_mm},
                                             board.turn_deg)),
        sim::BoardScene(spec, 4), photo);
    return geometry::estimate_bed_plane(as_core(camera), spec, view_of(image), board.thickness_mm);
}

}  // namespace calbox::test
