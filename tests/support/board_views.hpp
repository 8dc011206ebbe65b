#pragma once
// 12 MP views of the set-up's calibration chessboard with the twin's true corners, for the
// board-finding test and benchmark.
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "board/sim/camera_reference.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenes.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "core/geometry/types.hpp"
#include "tests/support/twin_fixtures.hpp"

namespace calbox::test {

struct BoardView {
    sim::GrayImage image;
    std::vector<sim::Vec2> truth;  // OpenCV's corner order
};

// An 11x8 chessboard of 20 mm squares held half a metre from the camera, tilted and turned.
inline std::vector<BoardView> render_board_views(int count) {
    const auto camera = hq_camera();
    const auto spec = geometry::parse_pattern_spec("chessboard:11x8@20");
    const sim::BoardScene board(spec, 2);
    sim::PhotoSettings photo;
    photo.supersample = 2;
    photo.noise_sigma_dn = 2.0;
    photo.blur_sigma_px = 1.2;  // a 12 MP sensor behind a small lens: about a pixel of blur
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> tilt(-25, 25), shift(-1, 1), distance(430, 560);
    std::vector<BoardView> views;
    while (static_cast<int>(views.size()) < count) {
        sim::Pose pose;
        pose.rotation = sim::rotation_from_vector(
            sim::Vec3{sim::radians(tilt(rng)), sim::radians(tilt(rng)), sim::radians(tilt(rng))});
        const double z = distance(rng);
        pose.translation_mm = sim::Vec3{shift(rng) * z * 0.2, shift(rng) * z * 0.1, z} -
                              pose.rotation * sim::Vec3{100, 70, 0};
        bool inside = true;
        for (const auto& c : {sim::Vec3{-30, -30, 0}, sim::Vec3{230, -30, 0},
                              sim::Vec3{-30, 170, 0}, sim::Vec3{230, 170, 0}}) {
            const auto px = sim::project_point(camera, pose, c);
            inside = inside && px.x > 5 && px.y > 5 && px.x < camera.width_px - 5 &&
                     px.y < camera.height_px - 5;
        }
        if (!inside) continue;
        photo.seed = views.size() + 1;
        BoardView v{sim::render_photo(camera, pose, board, photo), {}};
        for (const auto& f : board.features())
            v.truth.push_back(sim::project_point(camera, pose, f.position_mm));
        views.push_back(std::move(v));
    }
    return views;
}

// RMS from the truth, the corners matched to the nearest true corner (either detector may
// number the board from the other end).
inline double corner_rms(const std::vector<geometry::Point2>& found,
                         const std::vector<sim::Vec2>& truth) {
    double sum = 0;
    for (const auto& p : found) {
        double best = 1e30;
        for (const auto& t : truth)
            best = std::min(best, std::pow(p.x - t.x, 2) + std::pow(p.y - t.y, 2));
        sum += best;
    }
    return std::sqrt(sum / static_cast<double>(found.size()));
}

}  // namespace calbox::test
