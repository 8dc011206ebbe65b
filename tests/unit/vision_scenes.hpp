#pragma once
// Photographs of printed markers for the vision tests (test_vision*.cpp), with their corners' error
// against the truth the renderer drew.
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

namespace vision_scenes {

struct MarkerScene {
    sim::GrayImage image;
    std::map<std::pair<int, int>, sim::Vec2> truth;  // (id, corner) -> pixel
};

inline MarkerScene photograph_markers(double angle_deg,
                                      const std::string& dictionary = "DICT_4X4_50") {
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

inline double corner_rms(const MarkerScene& scene,
                         const std::vector<vision::DetectedMarker>& found) {
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

}  // namespace vision_scenes

using namespace vision_scenes;
