#pragma once
// How good a delta printer is, judged in the twin's truth: XY error of commanded against actual
// positions over the printable area with the best rotation and translation taken out, and its
// height map (the nozzle's height over the bed when commanded to z = 0).
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "core/solve/placement.hpp"

namespace calbox::test {

struct Judgement {
    double xy_rms = 0, xy_max = 0;
    double height_change = 0;  // largest change of the height map the commands made
    double height_range_before = 0, height_range_after = 0;
};

// Sends `commands` (then G28) to the twin and judges it on a 5 mm grid out to `radius_mm`.
inline Judgement judge(sim::DeltaTwin& twin, const std::vector<std::string>& commands,
                       double radius_mm = 75) {
    std::vector<sim::Vec3> grid;
    for (double x = -radius_mm; x <= radius_mm; x += 5)
        for (double y = -radius_mm; y <= radius_mm; y += 5)
            if (std::hypot(x, y) <= radius_mm) grid.push_back({x, y, 0.0});
    twin.home();
    std::vector<sim::Vec3> before;
    for (const auto& p : grid) before.push_back(twin.actual_position_mm(p));
    sim::GcodeRunner runner(twin, sim::ToolSettings{});
    for (const auto& line : commands) runner.run_line(line);
    runner.run_line("G28");
    std::vector<sim::Vec3> after;
    for (const auto& p : grid) after.push_back(twin.actual_position_mm(p));
    std::vector<geometry::Point2> actual_xy, commanded_xy;
    for (std::size_t i = 0; i < grid.size(); ++i)
        actual_xy.push_back({after[i].x, after[i].y}),
            commanded_xy.push_back({grid[i].x, grid[i].y});
    const auto placement = solve::best_rigid_placement(actual_xy, commanded_xy);
    Judgement j;
    double sum = 0;
    double low_before = 1e9, high_before = -1e9, low_after = 1e9, high_after = -1e9;
    for (std::size_t i = 0; i < grid.size(); ++i) {
        const auto p = placement.apply(actual_xy[i]);
        const double e = std::hypot(p.x - grid[i].x, p.y - grid[i].y);
        sum += e * e;
        j.xy_max = std::max(j.xy_max, e);
        j.height_change = std::max(j.height_change, std::abs(after[i].z - before[i].z));
        low_before = std::min(low_before, before[i].z),
        high_before = std::max(high_before, before[i].z);
        low_after = std::min(low_after, after[i].z), high_after = std::max(high_after, after[i].z);
    }
    j.xy_rms = std::sqrt(sum / static_cast<double>(grid.size()));
    j.height_range_before = high_before - low_before;
    j.height_range_after = high_after - low_after;
    return j;
}

}  // namespace calbox::test
