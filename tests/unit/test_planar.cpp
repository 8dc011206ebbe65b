// The planar (router) mode: the quasi-static error model, DETMAX, the hole-grid target, the
// measurement of a drilled sheet, and the whole cycle on ten hidden twin routers.
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
#include "core/solve/placement.hpp"
#include "core/targets/planar_target.hpp"
#include "tests/support/cycle_harness.hpp"
#include "tests/support/router_fixtures.hpp"

using namespace calbox;
using geometry::Point2;

namespace {

std::size_t parameter(const char* name) {
    const auto& table = models::planar_parameters();
    for (std::size_t j = 0; j < table.size(); ++j)
        if (std::string(table[j].name) == name) return j;
    FAIL(name);
    return 0;
}

// The seed's set-up: a 6 x 6 grid over its router's work area.
std::vector<Point2> seed_grid() {
    std::vector<Point2> points;
    for (int r = 0; r < 6; ++r)
        for (int c = 0; c < 6; ++c) points.push_back({25.0 + 50.0 * c, 25.0 + 50.0 * r});
    return points;
}

// The seed's reported constants (REFERENCE.md, 12-point design).
models::SeedPlanarForm seed_form() {
    return {1.16e-5, 3.91e-3, -6.40e-3, -3.44e-1, 2.33e-3, 5.60e-3, 0, -2.31e-5, -8.97e-5};
}

}  // namespace

TEST_GROUP(PlanarModel){};

TEST(PlanarModel, sensitivity_columns_are_the_chains_first_order_terms_worked_by_hand) {
    // At x = 100, y = 50, the tool 80 mm below the guides. By hand: theta x r with r from the
    // link's origin to the tool point; the x axis's origin at (x, y, 0), the y axis's at (0, y, 0).
    const auto rows = models::planar_sensitivity({100, 50}, 80);
    const auto at = [&](const char* name) {
        const auto j = parameter(name);
        return Point2{rows.ex[j], rows.ey[j]};
    };
    // x pitch (about y, rate with x): theta = (0, x, 0), r = (0, 0, -80): (-80 x, 0, 0).
    DOUBLES_EQUAL(-8000, at("x_pitch_rate").x, 1e-9);
    DOUBLES_EQUAL(0, at("x_pitch_rate").y, 1e-9);
    // Gantry yaw (about z, rate with y): theta = (0, 0, y), r = (x, 0, -80): (0, x y, 0).
    DOUBLES_EQUAL(0, at("gantry_yaw_rate").x, 1e-9);
    DOUBLES_EQUAL(5000, at("gantry_yaw_rate").y, 1e-9);
    // y pitch (about x, rate with y): theta = (y, 0, 0), r = (x, 0, -80): (0, 80 y, 0).
    DOUBLES_EQUAL(4000, at("y_pitch_rate").y, 1e-9);
    // Straightness: the x axis bows in y with x^2; the y axis in x with y^2.
    DOUBLES_EQUAL(10000, at("x_straightness").y, 1e-9);
    DOUBLES_EQUAL(2500, at("y_straightness").x, 1e-9);
    // The tool leaning about y by 1 rad would swing the point 80 mm towards -x.
    DOUBLES_EQUAL(-80, at("tool_tilt_about_y").x, 1e-9);
    DOUBLES_EQUAL(80, at("tool_tilt_about_x").y, 1e-9);
}

TEST(PlanarModel, the_seeds_reported_parameters_reproduce_its_planar_error_field) {
    const auto form = seed_form();
    const auto p = models::planar_from_seed_form(form, 1.0);
    double worst = 0;
    for (int i = 0; i <= 20; ++i)
        for (int k = 0; k <= 20; ++k) {
            const double x = 15.0 * i, y = 15.0 * k;
            const Point2 model = models::planar_error_mm(p, {x, y}, 1.0);
            const Point2 seed = form.error_mm({x, y}, 1.0);
            worst = std::max(worst, std::hypot(model.x - seed.x, model.y - seed.y));
        }
    CHECK(worst < 1e-12);
    // Its size at the seed's 36 points: around the 1.5 mm mean error norm it reported.
    std::vector<Point2> errors;
    for (const auto& q : seed_grid()) errors.push_back(form.error_mm(q, 1.0));
    const auto stats = models::norm_statistics(errors);
    UT_PRINT(("seed field at its grid: mean " + std::to_string(stats.mean_mm) + " max " +
              std::to_string(stats.max_mm))
                 .c_str());
    CHECK(stats.mean_mm > 0.5 && stats.mean_mm < 3);
}

TEST(PlanarModel, compensation_lands_on_the_intended_point) {
    const auto p = models::planar_from_seed_form(seed_form(), 1.0);
    for (const Point2 intended : {Point2{10, 20}, Point2{290, 15}, Point2{150, 280}}) {
        const Point2 command = models::planar_command_for(p, intended, 1.0);
        const Point2 e = models::planar_error_mm(p, command, 1.0);
        DOUBLES_EQUAL(intended.x, command.x + e.x, 1e-9);
        DOUBLES_EQUAL(intended.y, command.y + e.y, 1e-9);
    }
}

TEST(PlanarModel, the_fit_recovers_the_seeds_parameters_from_measurements_of_its_uncertainty) {
    // The seed's instrument: 47.3 um in x and 39 um in y at k = 2. The camera's frame turned and
    // shifted against the machine's.
    const auto form = seed_form();
    const auto truth = models::planar_from_seed_form(form, 1.0);
    const double angle = 0.3;
    std::mt19937 random(7);
    std::normal_distribution<double> unit(0, 1);
    const auto measure = [&](double sx, double sy) {
        std::vector<models::PlanarObservation> observations;
        for (const auto& c : seed_grid()) {
            const Point2 e = form.error_mm(c, 1.0);
            const Point2 at{c.x + e.x + sx * unit(random), c.y + e.y + sy * unit(random)};
            observations.push_back({c,
                                    {std::cos(angle) * at.x - std::sin(angle) * at.y + 40,
                                     std::sin(angle) * at.x + std::cos(angle) * at.y - 12},
                                    0.5 * (sx + sy)});
        }
        models::PlanarFitSettings settings;
        settings.abbe_height_mm = 1.0;
        return models::fit_planar_errors(observations, settings);
    };
    // The field a fit predicts against the truth's, a rigid motion apart (what the camera cannot
    // see), worst over the work area.
    const auto field_difference = [&](const models::PlanarFit& fit) {
        std::vector<Point2> fitted_field, true_field;
        for (int i = 0; i <= 10; ++i)
            for (int k = 0; k <= 10; ++k) {
                const double x = 30.0 * i, y = 30.0 * k;
                const auto f = models::planar_error_mm(fit.parameters, {x, y}, 1.0);
                const auto t = models::planar_error_mm(truth, {x, y}, 1.0);
                fitted_field.push_back({x + f.x, y + f.y});
                true_field.push_back({x + t.x, y + t.y});
            }
        const auto placement = solve::best_rigid_placement(fitted_field, true_field);
        double worst = 0;
        for (std::size_t i = 0; i < fitted_field.size(); ++i) {
            const Point2 placed = placement.apply(fitted_field[i]);
            worst =
                std::max(worst, std::hypot(placed.x - true_field[i].x, placed.y - true_field[i].y));
        }
        return worst;
    };
    // Without noise: the field is the seed's up to what a first-order model leaves of errors of
    // 6 mm turned by the 4 mrad its B term amounts to (a few micrometres).
    const auto exact = measure(0, 0);
    CHECK_EQUAL(9, exact.rank);  // six parameters and the placement's three
    CHECK_EQUAL(6u, exact.held.size());
    for (const char* held : {"x_pitch_rate", "x_roll_rate", "y_pitch_rate", "y_roll_rate",
                             "tool_tilt_about_x", "tool_tilt_about_y"})
        CHECK(!exact.fitted[parameter(held)]);
    // What they stand for here: the held ones' columns folded into the kept ones.
    DOUBLES_EQUAL(form.C, exact.parameters[parameter("x_scale")], 2e-4);
    DOUBLES_EQUAL(form.F, exact.parameters[parameter("y_scale")], 2e-4);
    DOUBLES_EQUAL(form.E + form.B, exact.parameters[parameter("xy_squareness")], 2e-4);
    DOUBLES_EQUAL(form.I, exact.parameters[parameter("x_straightness")], 1e-7);
    DOUBLES_EQUAL(form.A, exact.parameters[parameter("y_straightness")], 1e-7);
    DOUBLES_EQUAL(form.H, exact.parameters[parameter("gantry_yaw_rate")], 1e-7);
    const double exact_field = field_difference(exact);
    CHECK(exact_field < 0.01);
    // With the seed's noise: each parameter within its stated uncertainty of the exact fit.
    int outside_3_sigma = 0, compared = 0;
    double worst_field = 0;
    for (int trial = 0; trial < 20; ++trial) {
        const auto fit = measure(0.0473 / 2, 0.039 / 2);
        for (std::size_t j = 0; j < fit.parameters.size(); ++j) {
            if (!fit.fitted[j]) continue;
            ++compared;
            if (std::abs(fit.parameters[j] - exact.parameters[j]) > 3 * fit.uncertainty[j])
                ++outside_3_sigma;
        }
        worst_field = std::max(worst_field, field_difference(fit));
    }
    UT_PRINT(("fitted parameters outside 3 sigma: " + std::to_string(outside_3_sigma) + " of " +
              std::to_string(compared) + "; worst field difference " + std::to_string(worst_field) +
              " mm (noise-free " + std::to_string(exact_field) + " mm)")
                 .c_str());
    CHECK(outside_3_sigma <= 2);
    // 36 points at ~22 um: the fitted field over the work area within 50 um of the truth's.
    CHECK(worst_field < 0.05);
}

TEST(PlanarModel, detmax_beats_random_designs_of_the_same_size) {
    // A 13 x 13 grid at 25 mm over a 300 mm square; designs of 24 holes.
    std::vector<Point2> grid;
    for (int r = 0; r < 13; ++r)
        for (int c = 0; c < 13; ++c) grid.push_back({25.0 * c, 25.0 * r});
    const auto design = models::detmax_design(grid, 24, 40);
    CHECK_EQUAL(24u, design.size());
    std::vector<Point2> chosen;
    chosen.reserve(design.size());
    for (auto i : design) chosen.push_back(grid[i]);
    const double detmax = models::design_log_determinant(chosen, grid, 40);
    // The field error each design leaves, averaged over noisy measurements of one field.
    const auto truth = models::planar_from_seed_form(seed_form(), 40);
    std::mt19937 random(3);
    std::normal_distribution<double> noise(0, 0.01);
    const auto field_error = [&](const std::vector<Point2>& points) {
        double sum = 0;
        int n = 0;
        for (int trial = 0; trial < 10; ++trial) {
            std::vector<models::PlanarObservation> observations;
            for (const auto& c : points) {
                const Point2 e = models::planar_error_mm(truth, c, 40);
                observations.push_back(
                    {c, {c.x + e.x + noise(random), c.y + e.y + noise(random)}, 0.01});
            }
            models::PlanarFitSettings settings;
            settings.abbe_height_mm = 40;
            const auto fit = models::fit_planar_errors(observations, settings);
            std::vector<Point2> fitted, truly;
            for (const auto& g : grid) {
                const auto f = models::planar_error_mm(fit.parameters, g, 40);
                const auto t = models::planar_error_mm(truth, g, 40);
                fitted.push_back({g.x + f.x, g.y + f.y});
                truly.push_back({g.x + t.x, g.y + t.y});
            }
            const auto placement = solve::best_rigid_placement(fitted, truly);
            for (std::size_t i = 0; i < fitted.size(); ++i) {
                const Point2 p = placement.apply(fitted[i]);
                sum += std::hypot(p.x - truly[i].x, p.y - truly[i].y);
                ++n;
            }
        }
        return sum / n;
    };
    const double detmax_error = field_error(chosen);
    std::vector<double> random_dets, random_errors;
    std::mt19937 pick(11);
    for (int d = 0; d < 30; ++d) {
        std::vector<std::size_t> order(grid.size());
        for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
        std::shuffle(order.begin(), order.end(), pick);
        std::vector<Point2> points;
        for (std::size_t i = 0; i < 24; ++i) points.push_back(grid[order[i]]);
        random_dets.push_back(models::design_log_determinant(points, grid, 40));
        random_errors.push_back(field_error(points));
    }
    std::sort(random_errors.begin(), random_errors.end());
    const double best_random = *std::max_element(random_dets.begin(), random_dets.end());
    UT_PRINT(("log det: DETMAX " + std::to_string(detmax) + ", best of 30 random " +
              std::to_string(best_random) + "; mean field error DETMAX " +
              std::to_string(detmax_error) + " mm, random median " +
              std::to_string(random_errors[15]) + " mm")
                 .c_str());
    CHECK(detmax > best_random);
    CHECK(detmax_error < random_errors[15]);
    CHECK(detmax_error < random_errors[3]);  // better than 27 of the 30
}

TEST(PlanarModel, statistics_are_the_seeds_table) {
    const auto s = models::norm_statistics({{3, 4}, {0, 1}, {0, 2}, {0, 3}});
    DOUBLES_EQUAL(5, s.max_mm, 1e-12);
    DOUBLES_EQUAL(1, s.min_mm, 1e-12);
    DOUBLES_EQUAL(2.75, s.mean_mm, 1e-12);
    DOUBLES_EQUAL(2.5, s.median_mm, 1e-12);
    DOUBLES_EQUAL(1.75, s.q1_mm, 1e-12);
    DOUBLES_EQUAL(3.5, s.q3_mm, 1e-12);
    DOUBLES_EQUAL(std::sqrt(8.75 / 3), s.std_mm, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// The target, the measurement and the cycle on the twin.

namespace {

models::MachineFile router_machine() {
    return models::parse_machine_file(test::kRouterMachineToml, "router.toml");
}

// Where the twin really drilled each hole of a job.
std::vector<Point2> drilled(const sim::RouterTruth& truth, const std::string& job) {
    sim::RouterTwin twin(truth);
    std::vector<Point2> out;
    for (const auto& h : sim::drilled_hole_centres_mm(twin, job)) out.push_back({h.x, h.y});
    return out;
}

}  // namespace

TEST_GROUP(PlanarTarget){};

TEST(PlanarTarget, grid_fiducials_and_drilling_job) {
    const auto machine = router_machine();
    const auto t = targets::make_planar_target(machine);
    CHECK_EQUAL(12, t.columns);
    CHECK_EQUAL(12, t.rows);
    CHECK_EQUAL(143u, t.holes.size());
    DOUBLES_EQUAL(12.5, t.first_mm.x, 1e-12);
    DOUBLES_EQUAL(6.35, t.large_diameter_mm, 1e-12);
    // No symmetry of the grid maps the two large holes and the omitted one onto themselves.
    for (int s = 1; s < 8; ++s) {
        int kept = 0;
        for (const auto& h : t.holes)
            if (h.large) {
                const auto to = targets::apply_grid_symmetry(s, h.index, t.columns, t.rows);
                kept += targets::is_large_hole(to, t.columns, t.rows) ? 1 : 0;
            }
        const auto omitted = targets::apply_grid_symmetry(s, t.omitted, t.columns, t.rows);
        CHECK(kept < 2 || !(omitted == t.omitted));
    }
    // grbl: dwell in seconds, spindle on and off, every hole plunged to the cut depth.
    CHECK(t.job.find("M3 S12000") != std::string::npos);
    CHECK(t.job.find("G4 P0.30") != std::string::npos);
    CHECK(t.job.find("\nM5\nM2\n") != std::string::npos);
    std::size_t plunges = 0;
    for (std::size_t at = t.job.find("G1 Z-2.000"); at != std::string::npos;
         at = t.job.find("G1 Z-2.000", at + 1))
        ++plunges;
    CHECK_EQUAL(144u, plunges);  // and the hole approached from the other side
    CHECK(t.backlash_hole.has_value());
    CHECK(t.job.find("G0 X151.0000 Y151.0000") != std::string::npos);  // from +X +Y
    // The twin drills every hole where it was told to, when it has no errors.
    const auto holes = drilled(sim::RouterTruth{}, t.job);
    CHECK_EQUAL(144u, holes.size());
    for (std::size_t i = 0; i < t.holes.size(); ++i) {
        DOUBLES_EQUAL(t.holes[i].centre_mm.x, holes[i].x, 1e-9);
        DOUBLES_EQUAL(t.holes[i].centre_mm.y, holes[i].y, 1e-9);
    }
    DOUBLES_EQUAL(t.backlash_hole->centre_mm.x, holes.back().x, 1e-9);
    DOUBLES_EQUAL(150.0, holes.back().y, 1e-9);
    // Marlin dwells in milliseconds and has no program end.
    auto marlin = machine;
    marlin.firmware = "marlin";
    const auto m = targets::make_planar_target(marlin);
    CHECK(m.job.find("G4 P300") != std::string::npos);
    CHECK(m.job.find("M2") == std::string::npos);
}

TEST(PlanarTarget, too_small_an_area_or_too_large_a_tool_is_refused) {
    auto machine = router_machine();
    machine.bed_size_x_mm = 150;
    CHECK_THROWS(jobs::JobError, targets::make_planar_target(machine));
    machine = router_machine();
    machine.tool_width_mm = 8;
    CHECK_THROWS(jobs::JobError, targets::make_planar_target(machine));
}

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
    const auto placement = solve::best_rigid_placement(seen, real);
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

RouterOutcome calibrate_router(unsigned seed, const targets::PlanarTargetOptions& design = {}) {
    RouterCase router(seed, design);
    return test::run_mode_cycle(router);
}

void run_routers(unsigned first) {
    for (unsigned seed = first; seed < first + 5; ++seed) {
        const auto r = calibrate_router(seed);
        const double reduction = 1 - r.after.mean_mm / r.before.mean_mm;
        UT_PRINT(("router " + std::to_string(seed) + ": mean error norm " +
                  std::to_string(r.before.mean_mm) + " -> " + std::to_string(r.after.mean_mm) +
                  " mm (" + std::to_string(100 * reduction) + " % less), worst " +
                  std::to_string(r.before.max_mm) + " -> " + std::to_string(r.after.max_mm) +
                  " mm; fit residual " + std::to_string(r.solution.fit.residual_rms_mm) + " mm")
                     .c_str());
        // The seed's size of error, and the issue's bar: 95 % less, under 0.05 mm mean.
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

}  // namespace

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

// The issue's case: the drilled sheet filling part of the frame, the machine's bed around it
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
    const auto placement = solve::best_rigid_placement(seen, real);
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

TEST_GROUP(PlanarDesign){};

TEST(PlanarDesign,
     a_detmax_design_of_24_holes_leaves_a_residual_within_20_percent_of_the_full_grids) {
    const auto machine = router_machine();
    targets::PlanarTargetOptions design;
    design.only_nodes = modes::planar_design_nodes(machine, 24);
    CHECK_EQUAL(24u, design.only_nodes->size());
    CHECK_EQUAL(26u, targets::make_planar_target(machine, design).holes.size());  // + fiducials
    double full_sum = 0, design_sum = 0;
    for (unsigned seed : {2u, 5u, 9u}) {
        const auto full = calibrate_router(seed);
        const auto short_job = calibrate_router(seed, design);
        UT_PRINT(("router " + std::to_string(seed) + ": full grid leaves " +
                  std::to_string(full.after.mean_mm) + " mm, 24 DETMAX holes " +
                  std::to_string(short_job.after.mean_mm) + " mm (before " +
                  std::to_string(full.before.mean_mm) + ")")
                     .c_str());
        CHECK(short_job.after.mean_mm <= 1.2 * full.after.mean_mm);
        full_sum += full.after.mean_mm;
        design_sum += short_job.after.mean_mm;
    }
    CHECK(design_sum <= 1.2 * full_sum);
}

TEST_GROUP(PlanarFirmware){};

// The planar goal: under 0.05 mm mean and 95 % less; a machine already under the bar before the
// cycle (a Klipper printer calibrated again) is judged by the bar alone.
TEST(PlanarFirmware, the_goal_asks_a_share_less_only_of_a_machine_above_its_bar) {
    const auto goal = modes::planar_goal();
    const modes::ErrorFigures raw{0.30, 0.35, 0.5}, good{0.004, 0.005, 0.008},
        part{0.04, 0.05, 0.08}, still_good{0.003, 0.004, 0.007}, worse{0.06, 0.07, 0.1};
    CHECK(goal.met(raw, good));
    STRCMP_CONTAINS("86.7 % less (goal 95 %)", goal.shortfall(raw, part).c_str());
    STRCMP_CONTAINS("(goal under 0.05", goal.shortfall(raw, worse).c_str());
    CHECK(goal.met(good, still_good));
    CHECK(goal.met(good, good));
    STRCMP_CONTAINS("(goal under 0.05", goal.shortfall(good, worse).c_str());
}

TEST(PlanarFirmware, scale_and_skew_settings_leave_what_the_result_says) {
    const auto machine = router_machine();
    const auto r = calibrate_router(7);
    const auto f = modes::planar_firmware_settings(machine, r.solution);
    // The firmware's own correction: skew first (Marlin's x - y I), then steps per mm.
    const jobs::Correction firmware = [&](Point2 p) {
        return Point2{(p.x - f.skew * p.y) / (1 + f.scale_x), p.y / (1 + f.scale_y)};
    };
    const auto truth = sim::random_router_truth(7);
    const auto judged = sim::judge_router_fresh_holes(truth, machine, &firmware);
    UT_PRINT(("firmware settings: predicted to leave " + std::to_string(f.mean_left_mm) +
              " mm of " + std::to_string(f.mean_before_mm) +
              "; the twin: " + std::to_string(judged.after->mean_mm) + " mm of " +
              std::to_string(judged.before.mean_mm))
                 .c_str());
    CHECK(judged.after->mean_mm < judged.before.mean_mm);
    DOUBLES_EQUAL(f.mean_left_mm, judged.after->mean_mm, 0.25 * f.mean_left_mm);
    // grbl: the new steps per mm when the machine file gives them.
    auto with_steps = machine;
    with_steps.planar->steps_per_mm_x = 80;
    with_steps.planar->steps_per_mm_y = 80;
    const auto lines = modes::planar_firmware_settings(with_steps, r.solution).lines;
    bool x_line = false;
    for (const auto& l : lines)
        if (l.rfind("$100=", 0) == 0) {
            x_line = true;
            DOUBLES_EQUAL(80 / (1 + f.scale_x), std::stod(l.substr(5)), 1e-3);
        }
    CHECK(x_line);
}

TEST_GROUP(PlanarRoutersFirst){};
TEST(PlanarRoutersFirst, routers_1_to_5_are_corrected_in_the_twins_truth) {
    run_routers(1);
}

TEST_GROUP(PlanarRoutersSecond){};
TEST(PlanarRoutersSecond, routers_6_to_10_are_corrected_in_the_twins_truth) {
    run_routers(6);
}

// ---------------------------------------------------------------------------------------------
// A cartesian printer: the dots printed, photographed, measured and solved.

TEST_GROUP(PlanarPrinter){};

TEST(PlanarPrinter, a_cartesian_printers_printed_dots_give_its_scales_and_squareness) {
    const auto machine = models::parse_machine_file(R"toml(
[machine]
kind = "cartesian"
firmware = "marlin"
bed_size_x_mm = 200.0
bed_size_y_mm = 200.0
line_width_mm = 0.45
layer_height_mm = 0.2
[planar]
hole_pitch_mm = 20.0
margin_mm = 12.0
surface_height_mm = 0.2
)toml",
                                                    "printer.toml");
    const auto target = targets::make_planar_target(machine);
    CHECK_EQUAL(9, target.columns);
    CHECK(!target.backlash_hole.has_value());
    sim::CartesianErrors truth;
    truth.scale_error_x = 0.004;
    truth.scale_error_y = -0.003;
    truth.squareness_error_deg = 0.3;
    sim::CartesianTwin twin(truth);
    auto camera_model = test::hq_camera();
    camera_model.width_px = 2028, camera_model.height_px = 1520;
    camera_model.fx = camera_model.fy = 2850, camera_model.cx = 1014.8, camera_model.cy = 758.55;
    const auto pose = sim::look_at_pose({103, 97, 420}, {100, 100, 0}, 2);
    sim::PhotoSettings photo;
    photo.blur_sigma_px = 0.8;
    photo.noise_sigma_dn = 2;
    const auto picture =
        test::photo_of_print(camera_model, pose, test::print_on_twin(twin, target.job), photo);
    const auto camera = test::as_core(camera_model);
    const auto plane =
        test::plane_from_board(camera_model, pose, {"chessboard:15x11@10", {25, 160, 0}}, photo);
    const auto measured = modes::measure_planar(machine, camera, plane, test::view_of(picture));
    CHECK_EQUAL(80u, measured.holes.size());
    const auto solution = modes::solve_planar(machine, measured);
    const auto firmware = modes::planar_firmware_settings(machine, solution);
    UT_PRINT(("printer: x scale " + std::to_string(firmware.scale_x) + ", y scale " +
              std::to_string(firmware.scale_y) + ", skew " + std::to_string(firmware.skew) +
              " (the twin's 0.004, -0.003, " +
              std::to_string(std::tan(0.3 * 3.14159265358979 / 180)) + ")")
                 .c_str());
    // The twin's y axis leans towards +x: x moves tan(lean) (1 + y scale) per mm of y.
    DOUBLES_EQUAL(0.004, firmware.scale_x, 2e-4);
    DOUBLES_EQUAL(-0.003, firmware.scale_y, 2e-4);
    DOUBLES_EQUAL(std::tan(0.3 * 3.14159265358979 / 180) * (1 - 0.003), firmware.skew, 2e-4);
    const jobs::Correction correct = [&](Point2 p) {
        return modes::planar_command_for(solution, p);
    };
    const auto verdict = sim::judge_cartesian_fresh_points(truth, machine, &correct);
    UT_PRINT(("printer: fresh points " + std::to_string(verdict.before.mean_mm) + " -> " +
              std::to_string(verdict.after->mean_mm) + " mm mean")
                 .c_str());
    CHECK(verdict.after->mean_mm < 0.02);
    CHECK(verdict.after->mean_mm < 0.05 * verdict.before.mean_mm);
}
