// The appliance over several cycles: drift as the machine's change since its correction, and
// each mode meeting its goal on a camera's worst day.
#include "tests/unit/appliance_rig.hpp"

// Issue "Figures and drawings that mean what they say": drift is the machine's change since its
// last correction, measured the same way both times. For a mode whose correction the box keeps,
// that is the error jobs meet through it, not the raw machine's error the target shows.
TEST_GROUP(ApplianceDrift){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

namespace {

struct DriftFigures {
    double raw_mm, in_force_mm, truth_mm, drift_mm;
    bool needs_calibration;
};

// Three cycles on one twin: the first calibrates; the second finds the machine as the first left
// it; `change` then ages the machine, and the third finds that. Each figure is the mode's
// headline (a mean); the truth is the twin's judge on a fresh job through the kept correction.
std::vector<DriftFigures> three_cycles(const std::string& scenario,
                                       const std::function<void(sim::Scenario&)>& change) {
    Rig rig(fresh_dir("drift-" + fs::path(scenario).stem().string()),
            (fs::path(CALBOX_SOURCE_DIR) / scenario).string(), {});
    firmware::BoxNews news(rig.data, "test", {});
    std::int64_t now_unix_s = 1'700'000'000;
    const auto told = rig.cycle.subscribe(
        {{},
         {},
         [&](bool completed) { news.cycle_ended(rig.cycle, completed, now_unix_s += 600); },
         {},
         {}});
    const auto judge = sim::make_twin_judge(*rig.board.bench);
    std::vector<DriftFigures> out;
    for (int cycle = 1; cycle <= 3; ++cycle) {
        if (cycle == 3) rig.board.bench->change_machine(change);
        // What jobs meet now, in the twin's truth, through what the box keeps.
        const auto kept = rig.cycle.mode().kept_correction();
        const double truth =
            firmware::headline_mm((kept ? judge->after(kept) : judge->before()).figures);
        rig.ended = 0;
        rig.run_cycle();
        rig.check_cycles_completed(cycle);
        const auto& report = rig.cycle.report();
        CHECK(report.applied);
        out.push_back({firmware::headline_mm(*report.measured),
                       firmware::headline_mm(*report.in_force), truth, news.drift_mm().value_or(-1),
                       news.needs_calibration().value_or(true)});
        UT_PRINT((scenario + ": cycle " + std::to_string(cycle) + ": raw " +
                  number_text("%.4f", out.back().raw_mm) + " mm, through the kept correction " +
                  number_text("%.4f", out.back().in_force_mm) + " (the twin's truth " +
                  number_text("%.4f", truth) + "), drift " +
                  number_text("%.4f", out.back().drift_mm) +
                  (out.back().needs_calibration ? ", needs calibrating" : ""))
                     .c_str());
    }
    return out;
}

}  // namespace

// A delta's correction lives in the printer: its error as jobs meet it is its print as printed.
// The second cycle finds what the first verified (no drift, nothing to calibrate); a knock that
// turns tower A by 0.15 degree before the third shows as drift, as the twin's truth has it.
TEST(ApplianceDrift, a_delta_as_it_was_left_has_not_drifted_and_a_knocked_one_has) {
    const auto f = three_cycles("tests/scenarios/delta_cycle_small.toml", [](sim::Scenario& s) {
        s.delta_truth.tower_angle_trim_deg[0] += 0.15;
    });
    CHECK(f[0].raw_mm > 0.05);
    CHECK(std::abs(f[1].drift_mm) < 0.01);
    CHECK_FALSE(f[1].needs_calibration);
    CHECK(std::abs(f[2].in_force_mm - f[2].truth_mm) < 0.01);
    CHECK(f[2].drift_mm > 0.02);
}

TEST(ApplianceDrift, a_router_as_its_model_left_it_has_not_drifted_and_a_changed_one_has) {
    // The x axis' belt stretches by 0.05 %: 0.1 mm over 200 mm.
    const auto f = three_cycles("tests/scenarios/planar_small.toml",
                                [](sim::Scenario& s) { s.router_truth.scale_x += 0.0005; });
    CHECK(f[1].raw_mm > 0.05);
    CHECK(f[1].in_force_mm < 0.05);
    CHECK(std::abs(f[1].drift_mm) < 0.02);
    CHECK_FALSE(f[1].needs_calibration);
    CHECK(std::abs(f[2].in_force_mm - f[2].truth_mm) < 0.02);
    CHECK(f[2].drift_mm > 0.01);
}

// Each mode's whole cycle, set-up included, on a camera's worst day (the scenarios say which
// nuisances, at the strength that stopped the set-up before issue 44): the goal met as the twin
// judges it.
TEST_GROUP(ApplianceWorstDay){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

// A laminated board and a PEI bed under the box's lamp, a lens 5 px softer in its corners, three
// times the noise, JPEG at 68, through a 2 MP camera: the board is found with its glared corners
// set aside, and the rings' strands in the soft corners are too blurred for their widths to
// give heights (there the heights are the fit's; said in the log). Before, those heights came
// out 0.06 mm low and the corrected printer was 0.036 mm RMS off while its verification print
// said 0.013. Its metering puts the prints' bright strands at 225 (the camera's own exposure
// left them at 133).
TEST(ApplianceWorstDay, the_delta_meets_its_goal) {
    Rig rig(fresh_dir("worst-delta"),
            (fs::path(CALBOX_SOURCE_DIR) / "tests/scenarios/delta_worst_day.toml").string(), {});
    const auto before = rig.board.bench->judge_delta_printer();
    rig.run_cycle();
    rig.check_cycles_completed(1);
    const auto after = rig.board.bench->judge_delta_printer();
    const auto& report = rig.cycle.report();
    UT_PRINT(("worst day, delta: before XY " + std::to_string(before.xy_rms) + " mm RMS; after " +
              std::to_string(after.xy_rms) + ", " + std::to_string(after.xy_max) +
              " worst; verify measured " + std::to_string(report.verified->rms_mm))
                 .c_str());
    CHECK(before.xy_rms > 0.25);
    CHECK_TEXT(after.xy_rms <= 0.01, std::to_string(after.xy_rms).c_str());
    CHECK_TEXT(after.xy_max <= 0.03, std::to_string(after.xy_max).c_str());
    // What the box says of its own work is no rosier than what the twin finds (its verification
    // print, measured with most heights untold, reads a few thousandths worse).
    CHECK(report.verified->rms_mm >= after.xy_rms - 0.002);
    const auto said = [&rig](const std::string& text) {
        return std::any_of(rig.log.begin(), rig.log.end(), [&](const std::string& line) {
            return line.find(text) != std::string::npos;
        });
    };
    CHECK(said("corners set aside under glare"));
    CHECK(said("of their heights from the fit (the first: photo 1: marker "));
}

namespace {

// A worst-day cycle judged by the twin against its mode's own goal; the box's exposure log lines.
struct WorstDay {
    sim::TwinVerdict before, after;
    std::string shortfall;
    std::vector<std::string> exposures;  // "target: exposure ..." lines
    std::string measured;                // the "measure -> solve (...)" line
    nlohmann::json exposure_record;      // cycle-0001-exposure.json
};
WorstDay run_worst_day(const std::string& scenario, const std::string& dir) {
    Rig rig(fresh_dir(dir), (fs::path(CALBOX_SOURCE_DIR) / "tests/scenarios" / scenario).string(),
            {});
    const auto judge = sim::make_twin_judge(*rig.board.bench);
    WorstDay day;
    day.before = judge->before();
    rig.run_cycle();
    rig.check_cycles_completed(1);
    day.after = judge->after(rig.cycle.mode().kept_correction());
    day.shortfall = rig.cycle.mode().goal().shortfall(day.before.figures, day.after.figures);
    for (const auto& line : rig.log) {
        if (line.find(": exposure ") != std::string::npos) day.exposures.push_back(line);
        if (line.find("measure -> solve") != std::string::npos) day.measured = line;
    }
    if (const auto record = rig.data.read_file("cycle-0001-exposure.json"))
        day.exposure_record = nlohmann::json::parse(*record);
    UT_PRINT(
        ("worst day, " + scenario + ": before " + day.before.line + "; after " + day.after.line)
            .c_str());
    for (const auto& line : day.exposures) UT_PRINT(line.c_str());
    return day;
}

}  // namespace

// A drilled aluminium plate under the lamp: half the work area clipped at the camera's own
// exposure, where the sheet and a hole are both white. The box reads again at half the exposure,
// then puts the bright side at 225: nothing clipped, the goal met. (The holes in the plate's
// corners, under 5 px of blur, measure larger than the rest and are set aside as odd: lost to
// the lens, not the light.)
TEST(ApplianceWorstDay, the_router_meets_its_goal_with_its_own_exposure) {
    const auto day = run_worst_day("planar_worst_day.toml", "worst-router");
    CHECK_TEXT(day.shortfall.empty(), day.shortfall.c_str());
    CHECK(day.exposures.size() >= 2);
    STRCMP_CONTAINS("target: exposure ", day.exposures.front().c_str());
    STRCMP_CONTAINS("% clipped before, 0.0 % after", day.exposures.front().c_str());
    CHECK(day.exposures.front().find("0.0 % clipped before") == std::string::npos);
    // The record: each capture's readings (the camera's own exposure, then half of it) and the
    // exposure chosen, with the work area's clipped share before and after.
    const auto& record = day.exposure_record;
    CHECK_EQUAL(2u, record.size());
    const auto& target = record.at(0);
    STRCMP_EQUAL("target", target.at("what").get<std::string>().c_str());
    CHECK(target.at("readings").size() >= 2);
    const auto first_us = target.at("readings").at(0).at("exposure_us").get<long>();
    CHECK_EQUAL(first_us / 2, target.at("readings").at(1).at("exposure_us").get<long>());
    CHECK(target.at("work_area_clipped_before").get<double>() > 0.3);
    DOUBLES_EQUAL(0, target.at("work_area_clipped_after").get<double>(), 1e-3);
    CHECK(target.at("exposure_us").get<long>() < first_us);
    CHECK_FALSE(target.at("bracketed").get<bool>());
}

// A glass galvo plate under the lamp: its mirror image saturates a tenth of the work area while
// the plate's dark side sits near the noise (on an anodised plate, at the camera's own exposure,
// 47 of the 961 marks lay in clipped white and were lost). No one exposure holds both, so the
// target's capture is bracketed: a long exposure for the work area's middle, a short one for the
// bright side, merged pixel by pixel. Every mark is measured and the goal is met.
TEST(ApplianceWorstDay, the_galvo_meets_its_goal_with_every_mark_measured) {
    const auto day = run_worst_day("galvo_worst_day.toml", "worst-galvo");
    CHECK_TEXT(day.shortfall.empty(), day.shortfall.c_str());
    CHECK(day.exposures.size() >= 2);
    STRCMP_CONTAINS("% clipped before, 0.0 % after", day.exposures.front().c_str());
    STRCMP_CONTAINS("(961 marks, 0 missing)", day.measured.c_str());
    // The bracket in the cycle's record: both exposures, the share taken from the short one, the
    // work area's clipped share before and after.
    const auto& target = day.exposure_record.at(0);
    STRCMP_EQUAL("target", target.at("what").get<std::string>().c_str());
    CHECK(target.at("bracketed").get<bool>());
    const auto long_us = target.at("exposure_us").get<long>();
    const auto short_us = target.at("short_exposure_us").get<long>();
    CHECK_TEXT(long_us > 2 * short_us,
               (std::to_string(long_us) + " us and " + std::to_string(short_us)).c_str());
    const double from_short = target.at("from_short_share").get<double>();
    CHECK_TEXT(from_short > 0.01 && from_short < 0.5, std::to_string(from_short).c_str());
    CHECK(target.at("work_area_clipped_before").get<double>() > 0.05);
    DOUBLES_EQUAL(0, target.at("work_area_clipped_after").get<double>(), 1e-3);
    STRCMP_CONTAINS("merged", day.exposures.front().c_str());
}
