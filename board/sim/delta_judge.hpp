#pragma once
// How good a delta printer is, judged in the twin's truth (the twin's own judgement, used by
// `calbox sim verify` and the tests): XY error of commanded against actual
// positions over the printable area with the best rotation and translation taken out, and its
// height map (the nozzle's height over the bed when commanded to z = 0).
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"

namespace calbox::sim {

// The best rotation and translation of `from` onto `to` (closed-form 2-D Procrustes), applied
// to `from`: the twin's own, so that its judgement does not lean on the solver it judges.
inline std::vector<Vec3> rigidly_onto(const std::vector<Vec3>& from, const std::vector<Vec3>& to) {
    double fx = 0, fy = 0, tx = 0, ty = 0;
    const double n = static_cast<double>(from.size());
    for (std::size_t i = 0; i < from.size(); ++i)
        fx += from[i].x / n, fy += from[i].y / n, tx += to[i].x / n, ty += to[i].y / n;
    double dot = 0, cross = 0;
    for (std::size_t i = 0; i < from.size(); ++i) {
        const double ax = from[i].x - fx, ay = from[i].y - fy, bx = to[i].x - tx, by = to[i].y - ty;
        dot += ax * bx + ay * by;
        cross += ax * by - ay * bx;
    }
    const double angle = std::atan2(cross, dot), c = std::cos(angle), s = std::sin(angle);
    std::vector<Vec3> out;
    out.reserve(from.size());
    for (const auto& p : from) {
        const double ax = p.x - fx, ay = p.y - fy;
        out.push_back({c * ax - s * ay + tx, s * ax + c * ay + ty, p.z});
    }
    return out;
}

// Each point against where it was meant, the best rotation and translation taken out (the
// work's zero and heading are set by hand): the error norms' mean, RMS and worst. Throws
// MachineError for no points.
struct PlacedJudgement {
    double mean_mm = 0, rms_mm = 0, max_mm = 0;
    std::size_t points = 0;
};
inline PlacedJudgement judge_placed(const std::vector<Vec3>& reached,
                                    const std::vector<Vec3>& intended) {
    if (reached.empty() || reached.size() != intended.size())
        throw MachineError("judge: " + std::to_string(reached.size()) + " points reached for " +
                           std::to_string(intended.size()) + " meant");
    const auto placed = rigidly_onto(reached, intended);
    PlacedJudgement j;
    j.points = placed.size();
    double sum = 0, sum2 = 0;
    for (std::size_t i = 0; i < placed.size(); ++i) {
        const double e = std::hypot(placed[i].x - intended[i].x, placed[i].y - intended[i].y);
        sum += e;
        sum2 += e * e;
        j.max_mm = std::max(j.max_mm, e);
    }
    j.mean_mm = sum / static_cast<double>(j.points);
    j.rms_mm = std::sqrt(sum2 / static_cast<double>(j.points));
    return j;
}

struct DeltaJudgement {
    double xy_rms_before = 0, xy_max_before = 0;  // the printer as it was
    double xy_rms = 0, xy_max = 0;                // after the commands
    double height_change = 0;  // largest change of the height map the commands made
    double height_range_before = 0, height_range_after = 0;
};

// Sends `commands` to the twin as the printer takes them, then G28.
inline void send_commands(DeltaTwin& twin, const std::vector<std::string>& commands) {
    GcodeRunner runner(twin, ToolSettings{});
    for (const auto& line : commands) runner.run_line(line);
    runner.run_line("G28");
}

// Sends `commands` (then G28) to the twin and judges it on a 5 mm grid out to `radius_mm`.
inline DeltaJudgement judge_delta(DeltaTwin& twin, const std::vector<std::string>& commands,
                                  double radius_mm = 75) {
    std::vector<Vec3> grid;
    for (double x = -radius_mm; x <= radius_mm; x += 5)
        for (double y = -radius_mm; y <= radius_mm; y += 5)
            if (std::hypot(x, y) <= radius_mm) grid.push_back({x, y, 0.0});
    twin.home();
    std::vector<Vec3> before;
    for (const auto& p : grid) before.push_back(twin.actual_position_mm(p));
    send_commands(twin, commands);
    std::vector<Vec3> after;
    for (const auto& p : grid) after.push_back(twin.actual_position_mm(p));
    // XY error of actual positions against the grid, their best placement taken out.
    const auto xy_error = [&](const std::vector<Vec3>& actual, double& rms, double& worst) {
        const std::vector<Vec3> placed = rigidly_onto(actual, grid);
        double sum = 0;
        for (std::size_t i = 0; i < grid.size(); ++i) {
            const double e = std::hypot(placed[i].x - grid[i].x, placed[i].y - grid[i].y);
            sum += e * e;
            worst = std::max(worst, e);
        }
        rms = std::sqrt(sum / static_cast<double>(grid.size()));
    };
    DeltaJudgement j;
    xy_error(before, j.xy_rms_before, j.xy_max_before);
    xy_error(after, j.xy_rms, j.xy_max);
    double low_before = 1e9, high_before = -1e9, low_after = 1e9, high_after = -1e9;
    for (std::size_t i = 0; i < grid.size(); ++i) {
        j.height_change = std::max(j.height_change, std::abs(after[i].z - before[i].z));
        low_before = std::min(low_before, before[i].z),
        high_before = std::max(high_before, before[i].z);
        low_after = std::min(low_after, after[i].z), high_after = std::max(high_after, after[i].z);
    }
    j.height_range_before = high_before - low_before;
    j.height_range_after = high_after - low_after;
    return j;
}

}  // namespace calbox::sim
