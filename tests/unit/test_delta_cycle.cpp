// The delta mode end to end on the twin, judged in its truth (issue 6's acceptance): seeded
// printers off in every geometric parameter print the target; a tilted 12 MP camera with blur
// and noise photographs it on a bed that has cooled since; the box measures, fits and corrects;
// the twin takes the commands and is judged over the printable area. The classic bar method runs
// on the same photos beside it.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <random>
#include <sstream>
#include <string>

#include "board/sim/camera_reference.hpp"
#include "board/sim/delta_judge.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/scenes.hpp"
#include "core/geometry/line_fit.hpp"
#include "core/models/delta.hpp"
#include "core/models/delta_commands.hpp"
#include "core/modes/delta.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/geometry/placement.hpp"
#include "tests/support/cycle_harness.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;

namespace {

// A bar's length as the nozzle laid it: between where its end ticks' centrelines really are (the
// twin's own kinematics at their commanded ends), along the line through their middles.
double true_bar_length_mm(const targets::TargetBar& bar, sim::DeltaTwin& twin, double top_mm) {
    const auto actual = [&](geometry::Point2 at) {
        const auto p = twin.actual_position_mm({at.x, at.y, top_mm});
        return geometry::Point2{p.x, p.y};
    };
    std::array<geometry::Line, 2> ticks;
    std::array<geometry::Point2, 2> middles;
    for (std::size_t k = 0; k < 2; ++k) {
        const auto ends = bar.tick_ends_mm(k);
        const auto a = actual(ends[0]);
        const auto b = actual(ends[1]);
        const double l = std::hypot(b.x - a.x, b.y - a.y);
        ticks[k] = {a, {(b.x - a.x) / l, (b.y - a.y) / l}};
        middles[k] = actual(bar.ticks_mm[k]);
    }
    const double m = std::hypot(middles[1].x - middles[0].x, middles[1].y - middles[0].y);
    const geometry::Line centreline{
        middles[0], {(middles[1].x - middles[0].x) / m, (middles[1].y - middles[0].y) / m}};
    const auto p = geometry::intersect(ticks[0], centreline);
    const auto q = geometry::intersect(ticks[1], centreline);
    return std::hypot(q->x - p->x, q->y - p->y);
}

// One pass of the cycle: what the fit found and did, judged in the twin's truth after it.
struct PassFigures {
    double gap_range = 0;  // the nozzle's gap over the bed, as the fit found it
    modes::DeltaPassStep step = modes::DeltaPassStep::apply;
    double xy_rms = 0, xy_max = 0;  // the printer after this pass (the last sent, for a hold)
    double predicted_rms = 0;       // what the box predicted of it (the fit's own uncertainty)
};

struct CycleFigures {
    double feature_rms = 0, feature_worst = 0;
    double fit_xy_rms = 0, fit_xy_max = 0, range_before = 0, range_after = 0, before_rms = 0;
    double reprint_xy_rms = 0, reprint_xy_max = 0;  // the target printed again after the cycle
    double classic_xy_rms = 0;
    std::vector<double> bar_errors;
    double feature_sigma_mean = 0;   // the edge fits' share of the corners' sigma, on average
    double strand_height_worst = 0;  // heights from widths against the twin's, where pressed
    std::size_t markers_found = 0, markers_printed = 0;
    std::vector<PassFigures> passes;
};

// The passes as one line: "1: gap 0.282 mm, XY 0.0008/0.0025 | 2: holds".
std::string passes_text(const std::vector<PassFigures>& passes) {
    std::string out;
    for (std::size_t i = 0; i < passes.size(); ++i) {
        char b[120];
        const auto& p = passes[i];
        if (p.step == modes::DeltaPassStep::holds)
            std::snprintf(b, sizeof b, "%s%zu: gap %.3f mm, holds", i ? " | " : "", i + 1,
                          p.gap_range);
        else
            std::snprintf(b, sizeof b, "%s%zu: gap %.3f mm, XY %.4f/%.4f (predicted %.4f)",
                          i ? " | " : "", i + 1, p.gap_range, p.xy_rms, p.xy_max, p.predicted_rms);
        out += b;
    }
    return out;
}

// What a real photo has that the plain twin lacks (issue 12's harder twin): the defaults are
// the plain twin's matte black sheet, white filament and mild light.
struct PhotoConditions {
    const char* name = "plain";
    double bed_albedo = 0.08, material_albedo = 0.85;
    sim::StrokeSurface surface;
    double lighting_gradient = 0.1;
    double noise_sigma_dn = 2.0;
    double motion_blur_px = 0;
    int jpeg_quality = 0;
    // How the owner levelled the printer before the box saw it: "centre" (the height zeroed
    // there only), "paper" (a paper test at the towers and the centre), "probe" (G33).
    const char* levelled_by = "paper";
    // The box has the printer's own probe measure the gap before the first pass (G30 over the
    // link, [probe] at 76 mm): its heights go to that pass's fit.
    bool printer_probes = false;
};

// One seeded printer through the whole cycle, pass after pass as the box runs them
// (modes::next_delta_pass_step): the target printed on the printer as it stands, photographed by
// the same camera, measured, solved, and the correction sent, until the printer holds.
class DeltaCase {
  public:
    DeltaCase(unsigned seed, const PhotoConditions& look)
        : seed_(seed), look_(look), rng_(seed), u_(-1, 1) {
        auto& u = u_;
        auto& rng = rng_;
        truth_.diagonal_rod_mm = 250 + 1.5 * u(rng);
        for (auto& t : truth_.diagonal_rod_trim_mm) t = u(rng);
        truth_.radius_mm = 140 + u(rng);
        for (auto& a : truth_.tower_angle_trim_deg) a = 0.5 * u(rng);
        for (auto& e : truth_.endstop_offset_mm) e = -0.15 * (1 + u(rng));
        twin_ = sim::DeltaTwin(truth_, sim::DeltaParams{});
        twin_.zero_height_at_centre();
        if (std::string(look.levelled_by) == "paper") twin_.level_by_paper(68);
        if (std::string(look.levelled_by) == "probe") twin_.level_by_probe(76, 38);
        levelled_ = twin_.firmware();

        scenario_.machine = models::parse_machine_file(test::kDeltaMachineToml, "test");
        scenario_.machine.bed_material = "aluminium";
        scenario_.machine.bed_temperature_c = 60;
        // Photographed once the bed has cooled part of the way: 25 to 45 degrees.
        scenario_.photo_bed_temperature_c = 35 + 10 * u(rng);

        // The box's camera about 40 cm up, a few degrees off vertical, turned at random.
        bed_to_camera_ = sim::look_at_pose({25 * u(rng), -30 + 15 * u(rng), 400 + 10 * u(rng)},
                                           {3 * u(rng), 3 * u(rng), 0}, 20 * u(rng));
        photo_.blur_sigma_px = 0.7 + 0.2 * u(rng);
        photo_.noise_sigma_dn = look.noise_sigma_dn;
        photo_.vignetting = 0.15;
        photo_.lighting_gradient = look.lighting_gradient;
        photo_.lighting_direction_deg = look.surface.light_azimuth_deg;
        photo_.motion_blur_px = look.motion_blur_px;
        if (look.motion_blur_px > 0) photo_.motion_blur_direction_deg = 180 * u(rng);
        photo_.jpeg_quality = look.jpeg_quality;
        photo_.seed = seed;
        plane_ = test::plane_from_board(camera_, bed_to_camera_, {}, photo_);
        printable_ = scenario_.machine.bed_radius_mm;
        if (look.printer_probes) {
            const auto points = modes::probe_points({76, 0.01});
            probe_ = modes::probe_from_replies(
                "marlin", points, test::replies_of_twin(twin_, modes::probe_job("marlin", points)),
                0.01);
        }
    }

    // The box reads the printer's settings in force (M503) before each pass, and prints.
    sim::GrayImage make_target(int pass) {
        scenario_.machine.delta = sim::machine_settings(twin_.firmware());
        const models::MachineFile& machine = scenario_.machine;
        target_ = targets::make_delta_target(machine);
        target_job_ = jobs::write_gcode(target_->job, machine, "target");
        const auto laid = test::print_on_twin(twin_, target_job_);
        photo_.seed = seed_ + 1000 * static_cast<unsigned>(pass);
        return test::photo_of_print(camera_, bed_to_camera_,
                                    sim::carried_by_bed(laid, sim::bed_growth_at_photo(scenario_)),
                                    photo_, look_.bed_albedo, look_.material_albedo, look_.surface);
    }

    modes::DeltaMeasurement measure(const sim::GrayImage& print_photo, int pass) {
        const models::MachineFile& machine = scenario_.machine;
        const auto& target = *target_;
        auto measured = modes::measure_delta(machine, model_, plane_, {test::view_of(print_photo)},
                                             scenario_.photo_bed_temperature_c);
        CHECK_TEXT(measured.heights_from_fit, "the surface heights come from the fit");
        // The strands' heights from their widths, against the twin's where it pressed them.
        for (const auto& f : measured.features) {
            const double gap =
                twin_.actual_position_mm({f.commanded_mm.x, f.commanded_mm.y, f.commanded_mm.z}).z;
            const auto strand = sim::first_layer_strand(target.strand_section_mm2, gap, 1.0);
            if (strand.width_mm < 0.95 && !strand.free_bead)
                figures_.strand_height_worst = std::max(
                    figures_.strand_height_worst, std::abs(f.seen_at_height_mm - strand.height_mm));
        }
        if (pass == 1) first_pass_figures(measured);
        return measured;
    }

    bool solve_and_correct(const modes::DeltaMeasurement& measured, int pass) {
        const models::MachineFile& machine = scenario_.machine;
        const auto solution =
            modes::solve_delta(machine, modes::record_of(measured, machine, {"photo"}),
                               pass == 1 ? probe_ : std::vector<solve::ProbePoint>{});
        PassFigures p;
        p.gap_range = solution.fit.correction.predicted_height_range_now_mm;
        p.predicted_rms = solution.fit.correction.predicted_xy_rms_mm;
        p.step = modes::next_delta_pass_step(solution, pass);
        if (p.step != modes::DeltaPassStep::holds) {
            sent_.insert(sent_.end(), solution.commands.begin(), solution.commands.end());
            sim::send_commands(twin_, solution.commands);
        }
        sim::DeltaTwin judged(truth_, levelled_);
        const auto after = sim::judge_delta(judged, sent_, printable_);
        p.xy_rms = after.xy_rms, p.xy_max = after.xy_max;
        // What the box predicts of a correction it sends is its fit's own uncertainty carried
        // through it: not nothing (as the correction's design alone says), and the twin's truth
        // after it within twice that.
        if (p.step != modes::DeltaPassStep::holds && solution.method == modes::DeltaMethod::fit) {
            CHECK_TEXT(p.predicted_rms > 0.0005, passes_text({p}).c_str());
            CHECK_TEXT(p.xy_rms <= 2 * p.predicted_rms, passes_text({p}).c_str());
        }
        figures_.passes.push_back(p);
        return p.step == modes::DeltaPassStep::apply_then_measure_again;
    }

    // The printer as the passes left it, judged against the printer as it came.
    CycleFigures judge() {
        auto& figures = figures_;
        sim::DeltaTwin fixed(truth_, levelled_);
        const auto after = sim::judge_delta(fixed, sent_, printable_);
        figures.fit_xy_rms = after.xy_rms;
        figures.fit_xy_max = after.xy_max;
        figures.range_before = after.height_range_before;
        figures.range_after = after.height_range_after;
        figures.before_rms = after.xy_rms_before;
        // The verification print: the target again on the corrected printer, every stroke end's
        // commanded position against where the nozzle really laid it, placement taken out.
        {
            sim::GcodeRunner runner(fixed, sim::ToolSettings{});
            std::istringstream job(target_job_);
            runner.run(job);
            std::vector<sim::Vec3> commanded, laid_again;
            for (const auto& st : runner.result().strokes) {
                commanded.push_back(st.commanded_a_mm), commanded.push_back(st.commanded_b_mm);
                laid_again.push_back(st.a_mm), laid_again.push_back(st.b_mm);
            }
            const auto placed = sim::rigidly_onto(laid_again, commanded);
            double sum = 0;
            for (std::size_t i = 0; i < placed.size(); ++i) {
                const double e =
                    std::hypot(placed[i].x - commanded[i].x, placed[i].y - commanded[i].y);
                sum += e * e;
                figures.reprint_xy_max = std::max(figures.reprint_xy_max, e);
            }
            figures.reprint_xy_rms = std::sqrt(sum / static_cast<double>(placed.size()));
        }
        // The seed paper's classic rod correction from the first pass's bars, on the printer as
        // it came.
        models::DeltaGeometry classic = sim::machine_settings(levelled_);
        classic.diagonal_rod_mm = solve::classic_rod_length_mm(classic, first_bars_);
        sim::DeltaTwin classic_twin(truth_, levelled_);
        figures.classic_xy_rms =
            sim::judge_delta(classic_twin, models::marlin_commands(classic), printable_).xy_rms;

        char line[600];
        std::snprintf(
            line, sizeof line,
            "%s, seed %2u: features %.4f rms %.4f worst | bars %+.4f %+.4f %+.4f | XY before "
            "%.3f, after %.4f rms %.4f worst (re-print %.4f rms %.4f worst), classic %.3f | "
            "height range %.3f -> %.3f, strand heights %.4f worst | passes %s | markers "
            "read %zu of %zu",
            look_.name, seed_, figures.feature_rms, figures.feature_worst, figures.bar_errors[0],
            figures.bar_errors[1], figures.bar_errors[2], figures.before_rms, figures.fit_xy_rms,
            figures.fit_xy_max, figures.reprint_xy_rms, figures.reprint_xy_max,
            figures.classic_xy_rms, figures.range_before, figures.range_after,
            figures.strand_height_worst, passes_text(figures.passes).c_str(), figures.markers_found,
            figures.markers_printed);
        UT_PRINT(line);
        CHECK_TEXT(figures.passes.size() <= 3, "at most three passes");
        return figures;
    }

  private:
    void first_pass_figures(const modes::DeltaMeasurement& measured) {
        auto& figures = figures_;
        const auto& target = *target_;
        figures.markers_found = measured.frames.at(0).size();
        figures.markers_printed = measured.target.markers.size();
        // The share of each corner's sigma its edge fits gave, above measure's 0.005 mm
        // floor for what they cannot see (docs/formats.md, measurements.json).
        for (const auto& f : measured.features)
            figures.feature_sigma_mean +=
                std::sqrt(std::max(0.0, f.sigma_mm * f.sigma_mm - 0.005 * 0.005));
        figures.feature_sigma_mean /= static_cast<double>(measured.features.size());
        // Features as the fit uses them, against where the material really is.
        twin_.home();
        std::vector<geometry::Point2> seen, material;
        for (const auto& f : measured.features) {
            const auto r =
                twin_.actual_position_mm({f.commanded_mm.x, f.commanded_mm.y, f.commanded_mm.z});
            seen.push_back(f.measured_mm);
            material.push_back({r.x, r.y});
        }
        const auto placement = geometry::best_rigid_placement(seen, material);
        double sum = 0;
        for (std::size_t i = 0; i < seen.size(); ++i) {
            const auto p = placement.apply(seen[i]);
            const double e = std::hypot(p.x - material[i].x, p.y - material[i].y);
            sum += e * e;
            figures.feature_worst = std::max(figures.feature_worst, e);
        }
        figures.feature_rms = std::sqrt(sum / static_cast<double>(seen.size()));
        // Bars against where the twin really laid their end ticks.
        CHECK_EQUAL(3u, measured.bars.size());
        for (const auto& b : measured.bars) {
            const auto& bar = target.bars[static_cast<std::size_t>(b.tower - 'A')];
            const double truth_mm = true_bar_length_mm(bar, twin_, target.top_height_mm);
            figures.bar_errors.push_back(b.measured_mm - truth_mm);
            first_bars_.push_back({b.commanded_from_mm, b.commanded_to_mm, b.measured_mm});
        }
    }

    unsigned seed_;
    PhotoConditions look_;
    std::mt19937 rng_;
    std::uniform_real_distribution<double> u_;
    sim::DeltaParams truth_;
    sim::DeltaTwin twin_{sim::DeltaParams{}, sim::DeltaParams{}};
    sim::DeltaParams levelled_;
    sim::Scenario scenario_;
    const sim::CameraIntrinsics camera_ = test::hq_camera();
    const geometry::CameraModel model_ = test::as_core(camera_);
    sim::Pose bed_to_camera_;
    sim::PhotoSettings photo_;
    geometry::BedPlane plane_;
    double printable_ = 0;
    std::vector<solve::ProbePoint> probe_;
    std::optional<targets::DeltaTarget> target_;
    std::string target_job_;
    CycleFigures figures_;
    std::vector<std::string> sent_;  // every pass's commands, in the order the printer took them
    std::vector<solve::BarMeasurement> first_bars_;
};

CycleFigures run_cycle(unsigned seed, const PhotoConditions& look = {}) {
    DeltaCase printer(seed, look);
    return test::run_mode_cycle(printer);
}

// Five scenarios per group, so that ctest runs the two groups side by side.
void run_scenarios(unsigned first) {
    double bar_abs_sum = 0, bar_worst = 0, classic_sum = 0, worst_rms = 0;
    int bars = 0;
    for (unsigned seed = first; seed < first + 5; ++seed) {
        const auto f = run_cycle(seed);
        CHECK_TEXT(f.feature_rms <= 0.02, ("feature RMS " + std::to_string(f.feature_rms)).c_str());
        CHECK_TEXT(f.fit_xy_rms <= 0.01, ("XY RMS after " + std::to_string(f.fit_xy_rms)).c_str());
        CHECK_TEXT(f.fit_xy_max <= 0.03,
                   ("XY worst after " + std::to_string(f.fit_xy_max)).c_str());
        // Issue "Delta mode 3"'s printers levelled by hand: the gap varies by 0.1-0.5 mm.
        CHECK_TEXT(f.range_before >= 0.1 && f.range_before <= 0.5,
                   ("a paper test's bed range " + std::to_string(f.range_before)).c_str());
        CHECK_TEXT(f.strand_height_worst <= 0.03,
                   ("strand height from width " + std::to_string(f.strand_height_worst)).c_str());
        CHECK_TEXT(f.range_after <= f.range_before + 1e-6,
                   ("height range " + std::to_string(f.range_before) + " -> " +
                    std::to_string(f.range_after))
                       .c_str());
        // The target printed again on the corrected printer (README: 0.0012 mm RMS, 0.0026 worst).
        CHECK_TEXT(f.reprint_xy_rms <= 0.005,
                   ("re-printed pattern RMS " + std::to_string(f.reprint_xy_rms)).c_str());
        CHECK_TEXT(f.reprint_xy_max <= 0.015,
                   ("re-printed pattern worst " + std::to_string(f.reprint_xy_max)).c_str());
        for (double e : f.bar_errors) bar_abs_sum += std::abs(e), ++bars;
        for (double e : f.bar_errors) bar_worst = std::max(bar_worst, std::abs(e));
        classic_sum += f.classic_xy_rms;
        worst_rms = std::max(worst_rms, f.fit_xy_rms);
    }
    const double bar_mean = bar_abs_sum / bars;
    UT_PRINT(("bars: mean absolute error " + std::to_string(bar_mean) + " mm, worst " +
              std::to_string(bar_worst) + " mm; XY after the fit worst RMS " +
              std::to_string(worst_rms) + " mm; classic mean RMS " +
              std::to_string(classic_sum / 5) + " mm")
                 .c_str());
    // README: bars between their end ticks within 0.0007 mm mean absolute error, 0.0027 worst
    // (edge to edge they were 0.0017 and 0.0053; the seed paper: 0.75).
    CHECK_TEXT(bar_mean <= 0.003, ("bar mean absolute error " + std::to_string(bar_mean)).c_str());
    CHECK_TEXT(bar_worst <= 0.006, ("bar worst error " + std::to_string(bar_worst)).c_str());
    // README: the classic rod correction from the same bars leaves about 0.21 mm RMS, over a
    // hundred times what the fit leaves.
    const double classic_mean = classic_sum / 5;
    CHECK_TEXT(classic_mean >= 0.15 && classic_mean <= 0.35,
               ("classic mean RMS " + std::to_string(classic_mean)).c_str());
    CHECK_TEXT(worst_rms * 20 < classic_mean, "the fit leaves a twentieth of the classic error");
}

}  // namespace

TEST_GROUP(DeltaCycleFirst){};
TEST(DeltaCycleFirst, seeds_1_to_5_are_measured_and_corrected_in_the_twins_truth) {
    run_scenarios(1);
}

TEST_GROUP(DeltaCycleSecond){};
TEST(DeltaCycleSecond, seeds_6_to_10_are_measured_and_corrected_in_the_twins_truth) {
    run_scenarios(6);
}

// The harder twin (issue 12): each of a real photo's troubles alone, then all of them at once,
// each on its own seeded printer. README: "On harder photos".
namespace {

std::vector<PhotoConditions> harder_conditions() {
    std::vector<PhotoConditions> all;
    PhotoConditions c;
    c.name = "JPEG at quality 93";
    c.jpeg_quality = 93;
    all.push_back(c);
    c = {};
    c.name = "glossy filament, one lamp at 30 degrees";
    c.surface.gloss = 0.8;
    c.surface.light_azimuth_deg = 30;
    all.push_back(c);
    c = {};
    c.name = "grey filament on the black sheet";
    c.material_albedo = 0.30;
    all.push_back(c);
    c = {};
    c.name = "white filament on a light textured PEI sheet";
    c.bed_albedo = 0.55;
    c.surface.bed_texture = 0.15;
    all.push_back(c);
    c = {};
    c.name = "textured bed";
    c.surface.bed_texture = 0.5;
    all.push_back(c);
    c = {};
    c.name = "light from one side";
    c.lighting_gradient = 0.8;
    all.push_back(c);
    c = {};
    c.name = "motion blur 1.5 px";
    c.motion_blur_px = 1.5;
    all.push_back(c);
    c = {};
    c.name = "all together";
    c.material_albedo = 0.45;
    c.surface.bed_texture = 0.3;
    c.surface.gloss = 0.5;
    c.surface.light_azimuth_deg = -60;
    c.lighting_gradient = 0.5;
    c.motion_blur_px = 1.0;
    c.jpeg_quality = 93;
    all.push_back(c);
    return all;
}

void run_harder(std::size_t first, std::size_t end) {
    const auto all = harder_conditions();
    double bar_abs_sum = 0, bar_worst = 0;
    int bars = 0;
    for (std::size_t i = first; i < end; ++i) {
        const auto f = run_cycle(static_cast<unsigned>(21 + i), all[i]);
        const std::string name = all[i].name;
        // README, "On harder photos": the plain twin's bounds hold. A real first layer leaves a
        // marker unread where its strands lay as narrow free beads (the nozzle far off a bed
        // whose gap varies by half a millimetre) and the photo's trouble blurs their gaps: two
        // of nine at most.
        CHECK_TEXT(f.markers_found + 2 >= f.markers_printed,
                   (name + ": markers read " + std::to_string(f.markers_found)).c_str());
        CHECK_TEXT(f.feature_rms <= 0.01,
                   (name + ": feature RMS " + std::to_string(f.feature_rms)).c_str());
        CHECK_TEXT(f.fit_xy_rms <= 0.005,
                   (name + ": XY RMS after " + std::to_string(f.fit_xy_rms)).c_str());
        CHECK_TEXT(f.fit_xy_max <= 0.015,
                   (name + ": XY worst after " + std::to_string(f.fit_xy_max)).c_str());
        CHECK_TEXT(f.reprint_xy_rms <= 0.005,
                   (name + ": re-printed pattern RMS " + std::to_string(f.reprint_xy_rms)).c_str());
        CHECK_TEXT(
            f.reprint_xy_max <= 0.015,
            (name + ": re-printed pattern worst " + std::to_string(f.reprint_xy_max)).c_str());
        for (double e : f.bar_errors) bar_abs_sum += std::abs(e), ++bars;
        for (double e : f.bar_errors) bar_worst = std::max(bar_worst, std::abs(e));
    }
    const double bar_mean = bar_abs_sum / bars;
    UT_PRINT(("bars: mean absolute error " + std::to_string(bar_mean) + " mm, worst " +
              std::to_string(bar_worst) + " mm")
                 .c_str());
    // README: 0.0028 mm mean absolute error, 0.0056 worst (the all-together photo's; edge to
    // edge it was 0.017 mm).
    CHECK_TEXT(bar_mean <= 0.005, ("bar mean absolute error " + std::to_string(bar_mean)).c_str());
    CHECK_TEXT(bar_worst <= 0.01, ("bar worst error " + std::to_string(bar_worst)).c_str());
}

}  // namespace

TEST_GROUP(DeltaHarderFirst){};
TEST(DeltaHarderFirst, jpeg_gloss_grey_and_light_sheet_photos_calibrate_the_printer) {
    run_harder(0, 4);
}

TEST_GROUP(DeltaHarderSecond){};
TEST(DeltaHarderSecond, textured_bed_one_sided_light_motion_blur_and_all_together_calibrate) {
    run_harder(4, 8);
}

// Issue 12: photos with twice today's sensor noise still calibrate the printer, and measure says
// its corners are less certain rather than refusing them.
TEST_GROUP(DeltaNoisier){};
TEST(DeltaNoisier, twice_the_sensor_noise_completes_the_cycle_with_larger_uncertainties) {
    PhotoConditions today;
    PhotoConditions noisier;
    noisier.name = "twice the sensor noise";
    noisier.noise_sigma_dn = 2 * today.noise_sigma_dn;
    const auto a = run_cycle(31, today);
    const auto b = run_cycle(31, noisier);
    UT_PRINT(("corners' edge-fit sigma " + std::to_string(a.feature_sigma_mean) + " mm at 2 DN, " +
              std::to_string(b.feature_sigma_mean) + " mm at 4 DN")
                 .c_str());
    // The ring's centrelines average some forty profiles a side, and part of their scatter is
    // the strand's own unevenness, which the noise does not change: less than the corners' 1.4.
    CHECK_TEXT(b.feature_sigma_mean > a.feature_sigma_mean * 1.1,
               "the noisier photo's corners are given a larger uncertainty");
    CHECK_TEXT(b.fit_xy_rms <= 0.01, ("XY RMS after " + std::to_string(b.fit_xy_rms)).c_str());
    CHECK_TEXT(b.fit_xy_max <= 0.03, ("XY worst after " + std::to_string(b.fit_xy_max)).c_str());
    CHECK_TEXT(b.reprint_xy_rms <= 0.005,
               ("re-printed pattern RMS " + std::to_string(b.reprint_xy_rms)).c_str());
}

// Issue "Delta mode 3": printers levelled by hand as many owners do (a paper test at the three
// towers and the centre) print a first layer whose gap varies over the bed by tenths; a probe
// routine leaves it flat. The first calibrate in at most three passes (the second measuring the
// verification print laid on the bed the first levelled), the second in one; the strands'
// heights read from their widths match the twin's where the nozzle pressed them.
namespace {
void run_levelled(const char* levelled_by, unsigned first, bool printer_probes = false) {
    const bool by_probe = std::string(levelled_by) == "probe";
    double worst_rms = 0, worst_max = 0, worst_height = 0, widest_range = 0, narrowest = 1e9;
    std::size_t most_passes = 0;
    for (unsigned seed = first; seed < first + 5; ++seed) {
        PhotoConditions look;
        look.name = levelled_by;
        look.levelled_by = levelled_by;
        look.printer_probes = printer_probes;
        if (printer_probes) look.name = "paper, probed over the link";
        const auto f = run_cycle(seed, look);
        worst_rms = std::max(worst_rms, f.fit_xy_rms);
        worst_max = std::max(worst_max, f.fit_xy_max);
        worst_height = std::max(worst_height, f.strand_height_worst);
        widest_range = std::max(widest_range, f.range_before);
        narrowest = std::min(narrowest, f.range_before);
        most_passes = std::max(most_passes, f.passes.size());
        CHECK_TEXT(f.fit_xy_rms <= 0.01, ("XY RMS after " + std::to_string(f.fit_xy_rms)).c_str());
        CHECK_TEXT(f.fit_xy_max <= 0.03,
                   ("XY worst after " + std::to_string(f.fit_xy_max)).c_str());
        CHECK_TEXT(f.reprint_xy_rms <= 0.005,
                   ("re-printed pattern RMS " + std::to_string(f.reprint_xy_rms)).c_str());
        CHECK_TEXT(f.strand_height_worst <= 0.03,
                   ("strand height from width " + std::to_string(f.strand_height_worst)).c_str());
        if (printer_probes) CHECK_EQUAL(1u, f.passes.size());  // the probe measured the gap
        if (by_probe) {
            CHECK_TEXT(f.range_before <= 0.06,
                       ("a probe's bed range " + std::to_string(f.range_before)).c_str());
            CHECK_EQUAL(1u, f.passes.size());
        } else {
            CHECK_TEXT(f.range_before >= 0.1 && f.range_before <= 0.5,
                       ("a paper test's bed range " + std::to_string(f.range_before)).c_str());
            // The first pass alone already meets the goal; the passes are what make it sure.
            CHECK_TEXT(f.passes.front().xy_rms <= 0.01 && f.passes.front().xy_max <= 0.03,
                       "the first pass meets the goal");
        }
    }
    UT_PRINT((std::string(levelled_by) + (printer_probes ? ", probed over the link" : "") +
              ": bed ranges " + std::to_string(narrowest) + " to " + std::to_string(widest_range) +
              " mm; at most " + std::to_string(most_passes) + " passes; XY after worst RMS " +
              std::to_string(worst_rms) + " mm, worst " + std::to_string(worst_max) +
              " mm; strand heights within " + std::to_string(worst_height) + " mm")
                 .c_str());
}
}  // namespace

TEST_GROUP(DeltaPaperLevelled){};
TEST(DeltaPaperLevelled, five_printers_levelled_by_a_paper_test_calibrate_in_three_passes_at_most) {
    run_levelled("paper", 41);
}

TEST_GROUP(DeltaProbeLevelled){};
TEST(DeltaProbeLevelled, five_printers_levelled_by_a_probe_calibrate_in_one_pass) {
    run_levelled("probe", 51);
}

// The same printers as DeltaPaperLevelled, with the printer's own probe read over the link
// before the first pass: the gap is known, one pass suffices.
TEST_GROUP(DeltaPaperProbed){};
TEST(DeltaPaperProbed, the_same_printers_probed_over_the_link_calibrate_in_one_pass) {
    run_levelled("paper", 41, true);
}
