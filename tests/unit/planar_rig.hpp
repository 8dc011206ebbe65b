#pragma once
// What the planar (router) tests (test_planar*.cpp) share: a seed model, a router's machine file
// and drilled sheet, and a whole cycle on hidden twin routers.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/geometry/calibration.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "core/jobs/compensate.hpp"
#include "core/models/planar_errors.hpp"
#include "core/modes/goal.hpp"
#include "core/modes/planar.hpp"
#include "core/geometry/placement.hpp"
#include "core/targets/planar_target.hpp"
#include "tests/support/cycle_harness.hpp"
#include "tests/support/router_fixtures.hpp"

using namespace calbox;
using geometry::Point2;

namespace planar_rig {

inline std::size_t parameter(const char* name) {
    const auto& table = models::planar_parameters();
    for (std::size_t j = 0; j < table.size(); ++j)
        if (std::string(table[j].name) == name) return j;
    FAIL(name);
    return 0;
}

// The seed's set-up: a 6 x 6 grid over its router's work area.
inline std::vector<Point2> seed_grid() {
    std::vector<Point2> points;
    for (int r = 0; r < 6; ++r)
        for (int c = 0; c < 6; ++c) points.push_back({25.0 + 50.0 * c, 25.0 + 50.0 * r});
    return points;
}

// The seed's reported constants (REFERENCE.md, 12-point design).
inline models::SeedPlanarForm seed_form() {
    return {1.16e-5, 3.91e-3, -6.40e-3, -3.44e-1, 2.33e-3, 5.60e-3, 0, -2.31e-5, -8.97e-5};
}

}  // namespace planar_rig

namespace planar_rig {

inline models::MachineFile router_machine() {
    return models::parse_machine_file(test::kRouterMachineToml, "router.toml");
}

// Where the twin really drilled each hole of a job.
inline std::vector<Point2> drilled(const sim::RouterTruth& truth, const std::string& job) {
    sim::RouterTwin twin(truth);
    std::vector<Point2> out;
    for (const auto& h : sim::drilled_hole_centres_mm(twin, job)) out.push_back({h.x, h.y});
    return out;
}

}  // namespace planar_rig

namespace planar_rig {

// One cycle on a hidden router: drill the target, photograph it, measure, solve; then a fresh
// job run on the router as it was and through the compensated G-code, judged in its truth.
struct RouterOutcome {
    sim::RouterJudgement before, after;
    modes::PlanarSolution solution;
};

// One router under the box: the sheet drilled and photographed, measured, the error model
// solved, and judged on a fresh job through it in the twin's truth.
class RouterCase {
  public:
    RouterCase(unsigned seed, const targets::PlanarTargetOptions& design)
        : seed_(seed), design_(design), target_(targets::make_planar_target(machine_, design)) {}

    sim::GrayImage make_target(int) {
        test::DrillFaults faults;
        faults.seed = seed_;
        return test::photo_of_drilled_sheet(bench_, truth_, target_.job, faults);
    }
    modes::PlanarMeasurement measure(const sim::GrayImage& photo, int) {
        modes::PlanarMeasureSettings settings;
        settings.target = design_;
        return modes::measure_planar(machine_, camera_, plane_, test::view_of(photo), settings);
    }
    bool solve_and_correct(const modes::PlanarMeasurement& measured, int) {
        out_.solution = modes::solve_planar(machine_, measured);
        return false;  // one model
    }
    RouterOutcome judge() {
        const jobs::Correction correct = [this](Point2 p) {
            return modes::planar_command_for(out_.solution, p);
        };
        const auto verdict = sim::judge_router_fresh_holes(truth_, machine_, &correct);
        out_.before = verdict.before;
        out_.after = *verdict.after;
        return out_;
    }

  private:
    unsigned seed_;
    targets::PlanarTargetOptions design_;
    const models::MachineFile machine_ = router_machine();
    targets::PlanarTarget target_;
    const test::RouterBench bench_ = test::router_bench(0.5);
    const geometry::CameraModel camera_ = test::as_core(bench_.camera);
    const geometry::BedPlane plane_ = test::router_plane(bench_);
    const sim::RouterTruth truth_ = sim::random_router_truth(seed_);
    RouterOutcome out_;
};

inline RouterOutcome calibrate_router(unsigned seed,
                                      const targets::PlanarTargetOptions& design = {}) {
    RouterCase router(seed, design);
    return test::run_mode_cycle(router);
}

inline void run_routers(unsigned first) {
    for (unsigned seed = first; seed < first + 5; ++seed) {
        const auto r = calibrate_router(seed);
        const double reduction = 1 - r.after.mean_mm / r.before.mean_mm;
        UT_PRINT(("router " + std::to_string(seed) + ": mean error norm " +
                  std::to_string(r.before.mean_mm) + " -> " + std::to_string(r.after.mean_mm) +
                  " mm (" + std::to_string(100 * reduction) + " % less), worst " +
                  std::to_string(r.before.max_mm) + " -> " + std::to_string(r.after.max_mm) +
                  " mm; fit residual " + std::to_string(r.solution.fit.residual_rms_mm) + " mm")
                     .c_str());
        // The seed's size of error, and the bar: 95 % less, under 0.05 mm mean.
        CHECK(r.before.mean_mm > 1.0);
        CHECK(reduction >= 0.95);
        CHECK(r.after.mean_mm < 0.05);
        // The slack the hole drilled from the other side shows, against the twin's: within
        // 0.025 mm, the lead screws' cyclic error (5 mm lead, up to 0.006 mm) being half a
        // period off at the cell's middle from its corners.
        const auto truth = sim::random_router_truth(seed);
        CHECK(r.solution.backlash_mm.has_value());
        UT_PRINT(("  backlash " + std::to_string(r.solution.backlash_mm->x) + ", " +
                  std::to_string(r.solution.backlash_mm->y) + " mm; the twin's " +
                  std::to_string(truth.backlash_x_mm) + ", " + std::to_string(truth.backlash_y_mm))
                     .c_str());
        CHECK(std::abs(r.solution.backlash_mm->x - truth.backlash_x_mm) < 0.025);
        CHECK(std::abs(r.solution.backlash_mm->y - truth.backlash_y_mm) < 0.025);
    }
}

}  // namespace planar_rig

using namespace planar_rig;
