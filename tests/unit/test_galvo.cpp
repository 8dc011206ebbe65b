// The galvo mode on the twin (issue 17's acceptance): ten seeded scanners burn the circle grid,
// the seed paper's 5496 x 3672 camera photographs it, the box measures it, builds the correction
// table, and a fresh verification grid burned through the table is judged in the twin's truth.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <string>

#include "board/sim/delta_judge.hpp"
#include "board/sim/galvo_twin.hpp"
#include "core/models/galvo_field.hpp"
#include "core/modes/galvo.hpp"
#include "core/targets/galvo_target.hpp"
#include "tests/support/cycle_harness.hpp"
#include "tests/support/galvo_fixtures.hpp"

using namespace calbox;

namespace {

// The half-size camera 375 mm over the platform, a little off and turned: enough to index.
test::GalvoBench half_size_bench() {
    test::GalvoBench bench;
    bench.camera = test::galvo_camera(0.5);
    bench.bed_to_camera = sim::look_at_pose({3, -4, 375}, {0, 0, 0}, 2);
    bench.photo.blur_sigma_px = 0.8;
    bench.photo.noise_sigma_dn = 2;
    return bench;
}

// The machine file says how its burns show: dark on a light substrate, or light on dark.
models::MachineFile galvo_machine(bool dark_marks = true) {
    auto machine = models::parse_machine_file(test::kGalvoMachineToml, "test");
    machine.galvo->marks = dark_marks ? "dark" : "light";
    return machine;
}

// Fresh marks, half a pitch off the calibration grid's nodes, over the table's rectangle.
std::vector<sim::Vec2> verification_grid(const models::CorrectionTable& t, int count) {
    return sim::fresh_grid({t.min_x_mm, t.min_y_mm, t.max_x_mm, t.max_y_mm}, count);
}

sim::Vec2 through(const models::CorrectionTable& t, sim::Vec2 p) {
    const auto c = t.command_for({p.x, p.y});
    return {c.x, c.y};
}

// Where the twin's marks truly land for a 31 x 31 grid burned through `table` (no camera).
const models::SquareGrid kGrid{31, 110.0 / 31};
std::vector<std::optional<geometry::Point2>> exact_landings(
    const sim::GalvoTruth& truth,
    const models::CorrectionTable& table = models::identity_table(55)) {
    std::vector<std::optional<geometry::Point2>> landed;
    for (int r = 0; r < kGrid.count; ++r)
        for (int c = 0; c < kGrid.count; ++c) {
            const auto p = kGrid.node_mm(c, r);
            const auto m = sim::galvo_mark_position_mm(truth, through(table, {p.x, p.y}));
            landed.push_back(geometry::Point2{m.x, m.y});
        }
    return landed;
}

struct Figures {
    sim::GalvoJudgement before, after;
    modes::GalvoMeasurement measured;
    double seconds_measure = 0;
};

// The box over the field: the camera, its pose and the bed plane from a board, set up once
// and kept for every scanner put under it, as a real box would be.
struct Box {
    test::GalvoBench bench;
    geometry::CameraModel camera;
    geometry::BedPlane plane;
};

Box set_up_box(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    Box box;
    box.bench.camera = test::galvo_camera(1.0);
    // Over the field, the frame's height along one of the field's axes (the seed's set-up).
    box.bench.bed_to_camera =
        sim::look_at_pose({5 * u(rng), -5 + 3 * u(rng), 375 + 5 * u(rng)},
                          {2 * u(rng), 2 * u(rng), 0}, 90.0 * (seed % 4) + 2 * u(rng));
    box.bench.photo.blur_sigma_px = 0.8;
    box.bench.photo.noise_sigma_dn = 2.0;
    box.bench.photo.vignetting = 0.1;
    box.bench.photo.lighting_gradient = 0.1;
    box.bench.photo.seed = seed;
    box.camera = test::as_core(box.bench.camera);
    box.plane = test::plane_from_board(box.bench);
    return box;
}

// One scanner under the box: the grid burned and photographed, measured, one table solved, and
// the table judged on a fresh grid in the twin's truth.
class ScannerCase {
  public:
    ScannerCase(Box& box, unsigned seed, bool dark_marks)
        : box_(box), seed_(seed), dark_marks_(dark_marks), machine_(galvo_machine(dark_marks)) {}

    sim::GrayImage make_target(int) {
        truth_ = sim::random_galvo_truth(seed_, machine_.galvo->field_size_mm);
        truth_.substrate_height_mm = machine_.galvo->substrate_height_mm;
        box_.bench.dark_marks = dark_marks_;
        box_.bench.photo.seed = seed_;
        const auto target = targets::make_galvo_target(machine_);
        const auto job = jobs::write_gcode(target.job, machine_, "galvo grid");
        return test::photo_of_burned_grid(box_.bench, truth_, job);
    }
    modes::GalvoMeasurement measure(const sim::GrayImage& photo, int) {
        const auto start = std::chrono::steady_clock::now();
        f_.measured = modes::measure_galvo(machine_, box_.camera, box_.plane, test::view_of(photo));
        f_.seconds_measure =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        return f_.measured;
    }
    bool solve_and_correct(const modes::GalvoMeasurement& measured, int) {
        solution_ = modes::solve_galvo(machine_, measured, std::nullopt);
        return false;  // one table
    }
    Figures judge() {
        const auto& table = solution_->fit.table;
        const auto fresh = verification_grid(table, 30);
        f_.before = sim::judge_galvo(truth_, fresh, [](sim::Vec2 p) { return p; });
        f_.after = sim::judge_galvo(truth_, fresh, [&](sim::Vec2 p) { return through(table, p); });
        char line[300];
        std::snprintf(
            line, sizeof line,
            "scanner %2u: before %.4f mean %.4f max | after %.5f mean %.5f rms %.5f max | "
            "%zu marks, %zu missing, %zu extra, symmetry %d, sigma %.5f mm | measure %.2f s",
            seed_, f_.before.mean_mm, f_.before.max_mm, f_.after.mean_mm, f_.after.rms_mm,
            f_.after.max_mm, f_.measured.nodes.size(), f_.measured.missing.size(),
            f_.measured.extra_mm.size(), f_.measured.symmetry, solution_->measurement_sigma_mm,
            f_.seconds_measure);
        UT_PRINT(line);
        return f_;
    }

  private:
    Box& box_;
    unsigned seed_;
    bool dark_marks_;
    const models::MachineFile machine_;
    sim::GalvoTruth truth_;
    std::optional<modes::GalvoSolution> solution_;
    Figures f_;
};

Figures run_scanner(Box& box, unsigned seed, bool dark_marks) {
    ScannerCase scanner(box, seed, dark_marks);
    return test::run_mode_cycle(scanner);
}

// Five scanners under one box (seed..seed+4), dark marks on light and light on dark.
void run_scanners(unsigned first) {
    Box box = set_up_box(first);
    double worst_mean = 0, worst_max = 0, before_sum = 0;
    for (unsigned seed = first; seed < first + 5; ++seed) {
        const auto f = run_scanner(box, seed, seed % 3 != 0);
        CHECK_EQUAL(961u, f.measured.nodes.size());
        // The goal is 0.008 mean and 0.03 worst; the README claims 0.001 and 0.004.
        CHECK_TEXT(f.after.mean_mm <= 0.001,
                   ("mean after " + std::to_string(f.after.mean_mm)).c_str());
        CHECK_TEXT(f.after.max_mm <= 0.004,
                   ("worst after " + std::to_string(f.after.max_mm)).c_str());
        CHECK(f.before.mean_mm >= 0.05);
        worst_mean = std::max(worst_mean, f.after.mean_mm);
        worst_max = std::max(worst_max, f.after.max_mm);
        before_sum += f.before.mean_mm;
    }
    UT_PRINT(("five scanners: before " + std::to_string(before_sum / 5) +
              " mm mean; after: worst mean " + std::to_string(worst_mean) + " mm, worst mark " +
              std::to_string(worst_max) + " mm")
                 .c_str());
}

}  // namespace

TEST_GROUP(GalvoTarget){};

TEST(GalvoTarget, no_rotation_or_mirror_maps_the_large_marks_onto_themselves) {
    for (int n : {15, 31, 41}) {
        std::set<std::pair<int, int>> large;
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c)
                if (targets::is_large_mark({c, r}, n)) large.insert({c, r});
        CHECK_EQUAL(8u, large.size());
        for (int g = 1; g < 8; ++g) {
            std::size_t kept = 0;
            for (const auto& [c, r] : large) {
                const auto t = targets::apply_symmetry(g, {c, r}, n);
                kept += large.count({t.column, t.row});
            }
            // At least five large marks move onto small ones: three damaged marks cannot make a
            // wrong reading look right.
            CHECK_TEXT(
                large.size() - kept >= 5,
                ("symmetry " + std::to_string(g) + " keeps " + std::to_string(kept)).c_str());
        }
    }
}

TEST(GalvoTarget, symmetries_are_the_eight_of_the_square) {
    const int n = 31;
    std::set<std::vector<int>> images;
    for (int g = 0; g < 8; ++g) {
        std::vector<int> image;
        for (const targets::GridIndex i : {targets::GridIndex{0, 0}, {5, 1}}) {
            const auto t = targets::apply_symmetry(g, i, n);
            image.push_back(t.column), image.push_back(t.row);
        }
        images.insert(image);
    }
    CHECK_EQUAL(8u, images.size());
    const auto t = targets::apply_symmetry(1, {30, 0}, n);  // a quarter turn: +x to +y
    CHECK_EQUAL(30, t.column);
    CHECK_EQUAL(30, t.row);
}

TEST(GalvoTarget, grid_circles_and_job_as_the_seed_lays_them_out) {
    const auto machine = galvo_machine();
    const auto target = targets::make_galvo_target(machine);
    CHECK_EQUAL(31, target.grid_count);
    CHECK_EQUAL(31u * 31u, target.marks.size());
    // The grid alone, which measurements are matched against, is the job's grid.
    const auto grid = targets::galvo_grid(machine);
    STRCMP_EQUAL(target.fingerprint.c_str(), grid.fingerprint.c_str());
    CHECK(grid.job.toolpath.moves.empty());
    for (std::size_t i = 0; i < grid.marks.size(); ++i) {
        CHECK(grid.marks[i].index == target.marks[i].index);
        CHECK_EQUAL(target.marks[i].large, grid.marks[i].large);
    }
    DOUBLES_EQUAL(110.0 / 31, target.pitch_mm, 1e-12);
    DOUBLES_EQUAL(-15 * target.pitch_mm, target.marks.front().centre_mm.x, 1e-9);
    DOUBLES_EQUAL(15 * target.pitch_mm, target.marks.back().centre_mm.y, 1e-9);
    // Every working move stays inside its circle: 0.2 L or 0.4 L less half the spot.
    for (const auto& move : target.job.toolpath.moves) {
        if (move.kind == jobs::MoveKind::travel) continue;
        double nearest = 1e9;
        bool large = false;
        for (const auto& m : target.marks) {
            const double d = std::hypot(move.to.x - m.centre_mm.x, move.to.y - m.centre_mm.y);
            if (d < nearest) nearest = d, large = m.large;
        }
        CHECK(nearest <= (large ? 0.4 : 0.2) * target.pitch_mm - 0.05 + 1e-6);
    }
    const auto gcode = jobs::write_gcode(target.job, machine, "grid");
    CHECK(gcode.find("M3 S1000") != std::string::npos);  // grbl's laser power out of 1000
    const auto csv = targets::write_scanner_job_csv(target.job, machine);
    CHECK(csv.rfind("x_mm,y_mm,power\n", 0) == 0);
    auto router = machine;
    router.kind = "router";
    router.galvo.reset();
    CHECK_THROWS(jobs::JobError, targets::make_galvo_target(router));
    CHECK_THROWS(jobs::JobError, targets::make_galvo_target(machine, {5}));
}

TEST_GROUP(GalvoField){};

TEST(GalvoField, table_from_exact_landing_positions_corrects_to_the_micrometre) {
    // No camera: the field map from where the twin's marks truly land. What is left is the
    // interpolation and the table's resolution.
    const auto truth = sim::random_galvo_truth(3);
    auto landed = exact_landings(truth);
    landed[5 * 31 + 7].reset();  // a misfire: filled from its neighbours
    const auto fit = models::fit_galvo_field(kGrid, landed, models::identity_table(55));
    CHECK(fit.filled[5 * 31 + 7]);
    CHECK(fit.before.mean_mm > 0.1);
    const auto fresh = verification_grid(fit.table, 40);
    const auto after =
        sim::judge_galvo(truth, fresh, [&](sim::Vec2 p) { return through(fit.table, p); });
    UT_PRINT(("exact landings: before " + std::to_string(fit.before.mean_mm) + " mean, after " +
              std::to_string(after.mean_mm) + " mean " + std::to_string(after.max_mm) +
              " max, table interpolation " + std::to_string(fit.table_interpolation_max_mm))
                 .c_str());
    // README: 0.0001 mm mean, 0.0005 worst.
    CHECK(after.mean_mm < 0.0001);
    CHECK(after.max_mm < 0.0005);
}

TEST(GalvoField, the_nodes_scatter_about_the_smooth_field_is_told_apart_from_the_field) {
    // The twin's distortion alone (up to tenths of a millimetre, smooth) is no scatter; marks
    // each landing 0.5 um per axis off at random (the test's own draws) scatter by 0.5 * sqrt(2)
    // um in the plane, with a few spattered marks 20 um off that must not sway the figure.
    const auto truth = sim::random_galvo_truth(3);
    auto landed = exact_landings(truth);
    const auto smooth = models::fit_galvo_field(kGrid, landed, models::identity_table(55));
    CHECK(smooth.before.mean_mm > 0.1);
    CHECK_TEXT(smooth.node_scatter_mm < 0.00005, std::to_string(smooth.node_scatter_mm).c_str());
    std::mt19937 draws(11);
    std::normal_distribution<double> off(0, 0.0005);
    for (auto& mark : landed) *mark = {mark->x + off(draws), mark->y + off(draws)};
    for (const int spattered : {40, 300, 611}) landed[spattered]->x += 0.02;
    const auto noisy = models::fit_galvo_field(kGrid, landed, models::identity_table(55));
    DOUBLES_EQUAL(0.0005 * std::sqrt(2.0), noisy.node_scatter_mm, 0.0001);
}

TEST(GalvoField, a_second_pass_through_the_first_table_refines_it) {
    // The grid burned through the first table lands within a hundredth; the table refined from
    // it still corrects to the micrometre.
    const auto truth = sim::random_galvo_truth(5);
    const auto first =
        models::fit_galvo_field(kGrid, exact_landings(truth), models::identity_table(55));
    const auto second =
        models::fit_galvo_field(kGrid, exact_landings(truth, first.table), first.table);
    CHECK(second.before.max_mm < 0.01);  // the first table already corrected the grid
    const auto fresh = verification_grid(second.table, 40);
    const auto after =
        sim::judge_galvo(truth, fresh, [&](sim::Vec2 p) { return through(second.table, p); });
    CHECK(after.mean_mm < 0.0005);
}

TEST(GalvoField, table_round_trips_through_csv_to_the_micrometre) {
    const auto table = models::fit_galvo_field(kGrid, exact_landings(sim::random_galvo_truth(8)),
                                               models::identity_table(55))
                           .table;
    const auto read = models::table_from_csv(models::table_to_csv(table), "table.csv");
    CHECK_EQUAL(65, read.nodes);
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(-54, 54);
    double worst = 0;
    for (int i = 0; i < 2000; ++i) {
        const geometry::Point2 p{u(rng), u(rng)};
        const auto a = table.command_for(p), b = read.command_for(p);
        worst = std::max(worst, std::hypot(a.x - b.x, a.y - b.y));
    }
    CHECK(worst < 0.001);
    CHECK_THROWS(models::FieldError, models::table_from_csv("0,0,1,2,3\n", "bad.csv"));
    CHECK_THROWS(models::FieldError,
                 models::table_from_csv("0,0,0,0,0,0\n1,0,1,0,1,0\n0,1,0,1,0,1\n", "three.csv"));
}

TEST(GalvoField, too_few_marks_or_a_missing_border_is_refused) {
    const models::SquareGrid grid{11, 10};
    std::vector<std::optional<geometry::Point2>> landed;
    for (int r = 0; r < 11; ++r)
        for (int c = 0; c < 11; ++c) landed.push_back(grid.node_mm(c, r));
    auto no_border = landed;
    for (int r = 0; r < 11; ++r) no_border[static_cast<std::size_t>(r * 11)].reset();
    CHECK_THROWS(models::FieldError,
                 models::fit_galvo_field(grid, no_border, models::identity_table(50)));
    auto sparse = landed;
    for (std::size_t i = 0; i < sparse.size(); i += 3) sparse[i].reset();
    CHECK_THROWS(models::FieldError,
                 models::fit_galvo_field(grid, sparse, models::identity_table(50)));
}

TEST_GROUP(GalvoSpots){};

TEST(GalvoSpots, fixed_point_moments_agree_with_the_double_reference) {
    test::GalvoBench bench;
    bench.camera = test::galvo_camera(0.25);
    bench.bed_to_camera = sim::look_at_pose({0, 0, 375}, {0, 0, 0}, 0);
    bench.photo.blur_sigma_px = 0.8;
    bench.photo.noise_sigma_dn = 2;
    const auto machine = galvo_machine();
    const auto target = targets::make_galvo_target(machine);
    const auto photo = test::photo_of_burned_grid(bench, sim::GalvoTruth{},
                                                  jobs::write_gcode(target.job, machine, "grid"));
    const auto spots = vision::find_spots(test::view_of(photo));
    CHECK(spots.dark_marks);
    CHECK(spots.spots.size() >= 961u);
    vision::MomentWindow w;
    w.centre_px = spots.spots[400].centre_px;
    w.centre_px.x += 0.3;
    w.radius_px = 8;
    w.substrate_dn = 200;
    w.mark_dn = 30;
    w.noise_dn = 2;
    const auto a = vision::measure_spot_q16(test::view_of(photo), w);
    const auto b = vision::measure_spot_reference(test::view_of(photo), w);
    DOUBLES_EQUAL(b.centre_px.x, a.centre_px.x, 0.001);
    DOUBLES_EQUAL(b.centre_px.y, a.centre_px.y, 0.001);
    DOUBLES_EQUAL(b.area_px, a.area_px, 0.01);
}

TEST_GROUP(GalvoOrientation){};

TEST(GalvoOrientation, all_eight_ways_round_are_read_and_damage_is_reported) {
    // The scanner head turned by quarter turns on its mount, and with its x drive reversed: the
    // grid lies on the bed each of the square's eight ways. Three misfires (one a large mark)
    // and two spatter blobs (one fused to a mark) are told apart from the grid. A half-size camera
    // is enough to index.
    const auto machine = galvo_machine();
    const auto target = targets::make_galvo_target(machine);
    const auto job = jobs::write_gcode(target.job, machine, "grid");
    sim::BurnFaults faults;
    for (const targets::GridIndex i : {targets::GridIndex{3, 4}, {15, 16}, {27, 20}})
        faults.misfires_at_mm.push_back({target.at(i).centre_mm.x, target.at(i).centre_mm.y});
    faults.misfire_radius_mm = 0.45 * target.pitch_mm;
    test::GalvoBench bench = half_size_bench();
    const auto camera = test::as_core(bench.camera);
    const auto plane = test::plane_from_board(bench);
    std::set<int> symmetries;
    for (int way = 0; way < 8; ++way) {
        auto truth = sim::random_galvo_truth(2);
        truth.substrate_height_mm = 2;
        truth.rotation_deg += 90.0 * (way % 4);
        truth.x_reversed = way >= 4;
        // Spatter where the head throws it: one blob fused to the edge of mark (20, 10), one
        // free between four marks.
        const auto landed = [&](targets::GridIndex i, double dx, double dy) {
            return sim::galvo_mark_position_mm(
                truth, {target.at(i).centre_mm.x + dx, target.at(i).centre_mm.y + dy});
        };
        faults.spatter_at_mm = {landed({20, 10}, 0.8, 0),
                                landed({8, 8}, 0.5 * target.pitch_mm, 0.5 * target.pitch_mm)};
        bench.dark_marks = way % 2 == 0;
        const auto photo = test::photo_of_burned_grid(bench, truth, job, faults);
        const auto m = modes::measure_galvo(galvo_machine(bench.dark_marks), camera, plane,
                                            test::view_of(photo));
        CHECK_EQUAL(bench.dark_marks, m.dark_marks);
        // The blob that fused with a small mark takes that mark out too: its centroid would
        // have moved by a tenth of a millimetre.
        CHECK_EQUAL(957u, m.nodes.size());
        CHECK_EQUAL(4u, m.missing.size());
        CHECK(m.extra_mm.size() >= 2u);
        std::set<std::pair<int, int>> missing;
        for (const auto& i : m.missing) missing.insert({i.column, i.row});
        CHECK(missing.count({3, 4}) == 1 && missing.count({15, 16}) == 1 &&
              missing.count({27, 20}) == 1);
        CHECK(missing.count({20, 10}) == 1);
        symmetries.insert(m.symmetry);
        // Every mark indexed where it belongs: its measured position against where the twin put
        // that node's mark, the bed frame's placement in the world taken out.
        std::vector<sim::Vec3> seen, truly;
        for (const auto& node : m.nodes) {
            const auto p =
                sim::galvo_mark_position_mm(truth, {node.intended_mm.x, node.intended_mm.y});
            seen.push_back({node.measured_mm.x, node.measured_mm.y, 0});
            truly.push_back({p.x, p.y, 0});
        }
        const auto placed = sim::rigidly_onto(seen, truly);
        double worst = 0;
        for (std::size_t i = 0; i < placed.size(); ++i)
            worst = std::max(worst, std::hypot(placed[i].x - truly[i].x, placed[i].y - truly[i].y));
        UT_PRINT(("way " + std::to_string(way) + ": symmetry " + std::to_string(m.symmetry) +
                  ", worst mark against the twin " + std::to_string(worst) + " mm")
                     .c_str());
        CHECK(worst < 0.01);
    }
    CHECK_EQUAL(8u, symmetries.size());
}

TEST_GROUP(GalvoScannersFirst){};
TEST(GalvoScannersFirst, scanners_1_to_5_at_the_seed_camera_are_corrected_in_the_twins_truth) {
    run_scanners(1);
}

TEST_GROUP(GalvoScannersSecond){};
TEST(GalvoScannersSecond, scanners_6_to_10_at_the_seed_camera_are_corrected_in_the_twins_truth) {
    run_scanners(6);
}

// The case: a 116 mm plate filling part of the frame, the scanner's platform around it
// dark (it had 58 % of the pixels below Otsu's level, and no mark was found), grey or white.
TEST(GalvoSpots, a_plate_amid_a_dark_grey_or_white_platform_gives_every_mark) {
    const auto machine = galvo_machine();
    const auto target = targets::make_galvo_target(machine);
    const auto job = jobs::write_gcode(target.job, machine, "grid");
    test::GalvoBench bench = half_size_bench();
    const auto camera = test::as_core(bench.camera);
    const auto plane = test::plane_from_board(bench);
    auto truth = sim::random_galvo_truth(3);
    for (const double platform : {0.04, 0.5, 0.97}) {
        const auto photo = test::photo_of_burned_grid(bench, truth, job, {},
                                                      test::WorkOnBed{-58, -58, 58, 58, platform});
        const auto m = modes::measure_galvo(machine, camera, plane, test::view_of(photo));
        UT_PRINT(("platform " + std::to_string(platform) + ": " + std::to_string(m.nodes.size()) +
                  " marks, " + std::to_string(m.missing.size()) + " missing")
                     .c_str());
        CHECK_EQUAL(961u, m.nodes.size());
        CHECK(m.missing.empty());
    }
}
