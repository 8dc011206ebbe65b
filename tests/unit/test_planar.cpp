// The planar (router) mode: the quasi-static error model, DETMAX, the hole-grid target, the
// measurement of a drilled sheet, and the whole cycle on ten hidden twin routers.
#include "tests/unit/planar_rig.hpp"

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
        const auto placement = geometry::best_rigid_placement(fitted_field, true_field);
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
            const auto placement = geometry::best_rigid_placement(fitted, truly);
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
