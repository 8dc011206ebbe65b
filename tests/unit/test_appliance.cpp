// The appliance on the sim board: the cycle driven through the event loop on simulated time, the
// twin printer behind a real pty (termios driver, host protocol), the rendering camera; each
// fault the scenario can inject ends in the error state with one message, the error LED, nothing
// more sent to the printer, and idle again after a press. The twin judges the printer in its
// truth; the box never reads it.
#include "tests/unit/appliance_rig.hpp"

TEST_GROUP(ApplianceCycle){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

// The whole cycle on the fake clock, and every line the box sent.
TEST(ApplianceCycle, corrects_the_printer_and_sends_exactly_the_protocol) {
    Rig rig(prepared_dir("cycle"), kScenario.string(), {});
    const auto before = rig.board.bench->judge_delta_printer();
    rig.run_cycle();
    rig.check_cycles_completed(1);
    const auto after = rig.board.bench->judge_delta_printer();
    const auto& report = rig.cycle.report();
    const auto& passes = delta_of(rig.cycle).passes();
    UT_PRINT(("before XY " + std::to_string(before.xy_rms) + " mm RMS, " +
              std::to_string(before.xy_max) + " worst; after " + std::to_string(after.xy_rms) +
              ", " + std::to_string(after.xy_max) + "; verify measured " +
              std::to_string(report.verified->rms_mm) + " RMS, " +
              std::to_string(report.verified->max_mm) + " worst; box " +
              std::to_string(report.box_seconds) + " s")
                 .c_str());
    for (const auto& line : rig.log)
        if (line.find(": pass ") != std::string::npos) UT_PRINT(line.c_str());
    // The goal (XY RMS <= 0.01, worst <= 0.03), and the README's figures for this seeded
    // scenario on a real first layer: 0.257 (0.539) before, 0.0014 (0.0032) after three passes
    // (the third sends nothing), the last verification print 0.0012.
    CHECK(before.xy_rms > 0.25 && before.xy_rms < 0.26);
    CHECK(after.xy_rms <= 0.01);
    CHECK(after.xy_max <= 0.03);
    CHECK(after.xy_rms <= 0.002);
    CHECK(after.xy_max <= 0.005);
    CHECK(report.applied);
    CHECK(report.verified->rms_mm <= 0.01);
    CHECK(report.verified->rms_mm <= 0.002);
    // Its bed is only zeroed at the centre: the first pass finds the gap varying by 0.43 mm and
    // levels it; the second measures the verification print laid on that bed, finds 0.04 mm and
    // sends what is left (0.022 mm of height); the third, on the second's verification print,
    // would change 0.005 mm at most: the printer holds, nothing more is sent.
    CHECK_EQUAL(3u, passes.size());
    CHECK(passes[0].step == modes::DeltaPassStep::apply_then_measure_again);
    CHECK(passes[0].gap_range_mm > 0.3);
    CHECK(passes[1].step == modes::DeltaPassStep::apply_then_measure_again);
    CHECK(passes[1].gap_range_mm <= 0.1);
    CHECK(passes[2].step == modes::DeltaPassStep::holds);
    CHECK(passes[2].xy_change_mm <= 0.01 && passes[2].height_change_mm <= 0.01);
    DOUBLES_EQUAL(*passes[0].verify_xy_rms_mm, passes[1].measured_xy_rms_mm, 1e-12);
    DOUBLES_EQUAL(*passes[1].verify_xy_rms_mm, passes[2].measured_xy_rms_mm, 1e-12);
    // The console's `last` lists them, each with what it found and did.
    {
        firmware::BoxConfig config;
        firmware::LogBook log_book;
        firmware::Console console(
            {rig.cycle, config, rig.data, "calbox.toml", rig.data, log_book, "test", {}, {}});
        const std::string last = console.reply_to("last");
        STRCMP_CONTAINS(("\npass 1: gap varied " + number_text("%.3f", passes[0].gap_range_mm) +
                         " mm; moves the nozzle ")
                            .c_str(),
                        last.c_str());
        STRCMP_CONTAINS(": sent, measured again\npass 2: ", last.c_str());
        STRCMP_CONTAINS(": sent, measured again\npass 3: gap varied 0.0", last.c_str());
        STRCMP_CONTAINS(": holds, nothing sent\n", last.c_str());
        STRCMP_CONTAINS("\"step\":\"holds, nothing sent\"",
                        console.reply_to("last --json").c_str());
    }

    // The transcript: jobs each opened by N0 M110 N0, lines numbered on from 1, every checksum
    // right, nothing resent on a clean link.
    const auto jobs = jobs_of(rig.transcript());
    // the settings read, target print; per pass that sent something: M503 backup, the
    // correction, M503 read-back, the verification print (the next pass's target)
    CHECK_EQUAL(10u, jobs.size());
    CHECK(jobs[0] == std::vector<std::string>{"M503"});
    CHECK(jobs[1] == jobs[5]);
    CHECK(jobs[1] == jobs[9]);
    CHECK(std::find(jobs[1].begin(), jobs[1].end(), "G28") != jobs[1].end());
    for (std::size_t pass_start : {2u, 6u}) {
        CHECK(jobs[pass_start] == std::vector<std::string>{"M503"});
        CHECK_EQUAL(3u, jobs[pass_start + 1].size());
        STRCMP_CONTAINS("M665 L", jobs[pass_start + 1][0].c_str());
        STRCMP_CONTAINS("M666 X", jobs[pass_start + 1][1].c_str());
        STRCMP_EQUAL("M500", jobs[pass_start + 1][2].c_str());
        CHECK(jobs[pass_start + 2] == std::vector<std::string>{"M503"});
    }
    CHECK(jobs[7] == delta_of(rig.cycle).solution()->commands);
    CHECK(jobs[3] != jobs[7]);
    // The record: measurements, each pass's result and settings backup; revert's backup is the
    // one from before the cycle.
    CHECK(rig.data.read_file("cycle-0001-result.json").has_value());
    CHECK(rig.data.read_file("cycle-0001-pass-2-result.json").has_value());
    CHECK(rig.data.read_file("cycle-0001-verify-measurements.json").has_value());
    CHECK(rig.data.read_file("cycle-0001-pass-2-verify-measurements.json").has_value());
    CHECK(rig.data.read_file("cycle-0001-pass-3-result.json").has_value());
    CHECK_FALSE(rig.data.read_file("cycle-0001-pass-3-backup.gcode").has_value());
    const auto backup = rig.data.read_file("cycle-0001-backup.gcode");
    CHECK(backup.has_value());
    STRCMP_CONTAINS("M665 L250.000 R140.000", backup->c_str());
    const auto second_backup = rig.data.read_file("cycle-0001-pass-2-backup.gcode");
    CHECK(second_backup.has_value());
    CHECK(second_backup->find("M665 L250.000 R140.000") == std::string::npos);
    CHECK(rig.board.display->frames_shown() > 5);
}

// Issue "Delta mode 3": a printer with a probe ([probe]) is probed over the link on the clear
// bed before the target is printed; the probe measured the gap, so the same printer the test
// above takes three passes for calibrates in one.
TEST(ApplianceCycle, a_printer_with_a_probe_is_probed_first_and_calibrated_in_one_pass) {
    Rig rig(prepared_dir("probe"), scenario_with("probe", "[probe]\nradius_mm = 76"), {});
    rig.run_cycle();
    rig.check_cycles_completed(1);
    const auto after = rig.board.bench->judge_delta_printer();
    const auto& passes = delta_of(rig.cycle).passes();
    UT_PRINT(("probed printer after the cycle: XY " + std::to_string(after.xy_rms) + " mm RMS, " +
              std::to_string(after.xy_max) + " mm worst, gap range " +
              std::to_string(after.height_range_after) + " mm")
                 .c_str());
    // The goal, and the README's figures: 0.0022 (0.0066) after one pass, against three passes'
    // 0.0014 (0.0032) without the probe; the gap then flat within 0.008 mm.
    CHECK(after.xy_rms <= 0.01 && after.xy_max <= 0.03);
    CHECK(after.xy_rms <= 0.003);
    CHECK(after.xy_max <= 0.008);
    CHECK(after.height_range_after <= 0.01);
    CHECK_EQUAL(1u, passes.size());
    CHECK(passes[0].step == modes::DeltaPassStep::apply);
    CHECK(passes[0].gap_range_mm > 0.3);  // as uneven as above
    CHECK(delta_of(rig.cycle).solution()->heights_from_probe);
    // the settings read, the probe job, the target print, the backup, the correction, the
    // read-back, the verification print
    const auto jobs = jobs_of(rig.transcript());
    CHECK_EQUAL(7u, jobs.size());
    CHECK_EQUAL(21u, jobs[1].size());
    STRCMP_EQUAL("G28", jobs[1].front().c_str());
    STRCMP_EQUAL("G30 X0.00 Y0.00", jobs[1][1].c_str());
    STRCMP_EQUAL("G30 X-65.82 Y-38.00", jobs[1][8].c_str());  // tower A's way, 76 mm out
    STRCMP_EQUAL("G28", jobs[1].back().c_str());
    const auto probe = rig.data.read_file("cycle-0001-probe.csv");
    CHECK(probe.has_value());
    CHECK_EQUAL(19u, modes::probe_from_file(*probe, "probe.csv").size());
    bool logged = false;
    for (const auto& line : rig.log) {
        if (line.find("cycle 1: the printer's probe: 19 points, the nozzle's gap ranging 0.") ==
            std::string::npos)
            continue;
        UT_PRINT(line.c_str());
        logged = true;
    }
    CHECK_TEXT(logged, "the probe's log line");
}

// A display that fails mid-use (here its directory replaced by a file) is told once; the cycle
// completes and corrects the printer all the same.
TEST(ApplianceCycle, a_failing_display_is_told_once_and_the_cycle_goes_on) {
    Rig rig(prepared_dir("failing_display"), kScenario.string(), {});
    fs::remove_all(rig.dir / "display");
    std::ofstream(rig.dir / "display") << "not a directory\n";
    rig.run_cycle();
    rig.check_cycles_completed(1);
    const auto told = std::count_if(rig.log.begin(), rig.log.end(), [](const std::string& l) {
        return l.rfind("display: ", 0) == 0 &&
               l.find(": cannot write the frame") != std::string::npos &&
               l.find("(the box goes on without it)") != std::string::npos;
    });
    CHECK_EQUAL(1, told);
    CHECK(rig.board.bench->judge_delta_printer().xy_rms <= 0.0045);
}

TEST(ApplianceCycle, a_long_press_at_review_cancels_and_sends_no_correction) {
    Rig rig(prepared_dir("cancel"), kScenario.string(), {});
    rig.intercept = [&rig](firmware::Prompt p) {
        if (p != firmware::Prompt::review) return false;
        rig.board.lines->press(2000ms);
        return true;
    };
    rig.run_cycle();
    CHECK(rig.cycle.state() == firmware::CycleState::idle);
    CHECK_EQUAL(0, rig.cycle.cycles_completed());
    for (const auto& line : rig.transcript()) CHECK(line.find("M665") == std::string::npos);
    const auto after = rig.board.bench->judge_delta_printer();
    CHECK(after.xy_rms > 0.2);  // untouched
}

// Every other waiting state: a long press (or the console's cancel) there returns to idle with
// the ready LED, the light off and nothing more sent; the set-up keeps nothing half-done.
TEST(ApplianceCycle, each_waiting_state_cancels_to_idle) {
    struct Case {
        const char* name;
        firmware::Prompt prompt;
        bool with_camera, with_plane, from_console;
        firmware::CycleState waiting_in;
    };
    const Case cases[] = {
        {"views", firmware::Prompt::hold_calibration_board, false, false, false,
         firmware::CycleState::setup_camera},
        {"plane", firmware::Prompt::lay_plane_board, true, false, false,
         firmware::CycleState::setup_plane},
        {"bed", firmware::Prompt::clear_bed, true, true, true, firmware::CycleState::make_target},
    };
    for (const auto& c : cases) {
        const fs::path dir = fresh_dir(std::string("cancel_") + c.name);
        if (c.with_camera) fs::copy_file(prepared_setup() / "camera.yaml", dir / "camera.yaml");
        if (c.with_plane) {
            for (const char* f : {"plane.yaml", firmware::kReferenceFile})
                fs::copy_file(prepared_setup() / f, dir / f);
        }
        Rig rig(dir, kScenario.string(), {});
        bool asked = false;
        rig.intercept = [&](firmware::Prompt p) {
            if (p != c.prompt) return false;
            asked = true;
            CHECK(rig.cycle.state() == c.waiting_in);
            CHECK(rig.board.lines->led(hal::Led::ready));  // waiting for a person
            if (c.from_console)
                rig.cycle.cancel("cancelled from the console");
            else
                rig.board.lines->press(2000ms);
            return true;
        };
        rig.run_cycle();
        CHECK_TEXT(asked, c.name);
        CHECK(rig.cycle.state() == firmware::CycleState::idle);
        CHECK(rig.board.lines->led(hal::Led::ready));
        CHECK_FALSE(rig.board.lines->led(hal::Led::error));
        CHECK_FALSE(rig.board.lines->light());
        rig.check_nothing_more_sent(20);
        CHECK_EQUAL(c.with_camera, fs::exists(dir / "camera.yaml"));
        CHECK_EQUAL(c.with_plane, fs::exists(dir / "plane.yaml"));
    }
}

// A knock on the camera after the plane was taken: the next cycle stops at its start, before
// anything is made, naming the move; with the plane taken again the check passes.
TEST(ApplianceCycle, a_knocked_camera_stops_the_cycle_before_anything_is_made) {
    Rig rig(prepared_dir("knocked"), kScenario.string(), {});
    rig.board.bench->knock_camera(0.05, {0, 0, 0});  // 0.35 mm on the bed at 400 mm
    rig.run_cycle();
    CHECK(rig.cycle.failed_in() == firmware::CycleState::setup_plane);
    STRCMP_CONTAINS("the camera has moved since the plane was taken: 4 of 4 reference marks",
                    rig.cycle.error().c_str());
    STRCMP_CONTAINS("(limit 0.050 mm)", rig.cycle.error().c_str());
    for (const auto& line : rig.transcript())
        CHECK_TEXT(command_of(line).rfind("G1", 0) != 0, ("made: " + line).c_str());
    check_error_state(rig, "take the plane again");

    CHECK(rig.cycle.take_plane().empty());
    rig.run_until([&] { return rig.cycle.state() == firmware::CycleState::idle; });
    STRCMP_CONTAINS("4 reference marks", rig.log.back().c_str());
    rig.intercept = [&rig](firmware::Prompt p) {
        if (p != firmware::Prompt::clear_bed) return false;
        rig.board.lines->press(2000ms);  // far enough: the check passed
        return true;
    };
    const std::size_t logged = rig.log.size();
    rig.start();
    rig.run_until([&] { return rig.cycle.state() == firmware::CycleState::idle; });
    bool checked = false;
    for (std::size_t i = logged; i < rig.log.size(); ++i)
        checked =
            checked || rig.log[i].find("camera check: 4 of 4 reference marks") != std::string::npos;
    CHECK_TEXT(checked, "no camera check in the log");
}

// Cancelled at the bed-clearing before the verification print, the correction stays applied
// (it was read back) and nothing more is printed.
TEST(ApplianceCycle, a_cancel_before_the_verification_print_keeps_the_applied_correction) {
    Rig rig(prepared_dir("cancel_verify"), kScenario.string(), {});
    rig.intercept = [&rig](firmware::Prompt p) {
        if (p != firmware::Prompt::clear_bed || rig.cycle.state() != firmware::CycleState::verify)
            return false;
        rig.board.lines->press(2000ms);
        return true;
    };
    rig.run_cycle();
    CHECK(rig.cycle.state() == firmware::CycleState::idle);
    CHECK(rig.cycle.report().applied);
    CHECK_EQUAL(0, rig.cycle.cycles_completed());
    const auto t = rig.transcript();
    STRCMP_EQUAL("M503", command_of(t.back()).c_str());  // the read-back, then nothing
    CHECK(rig.board.bench->judge_delta_printer().xy_rms <= 0.01);
}

TEST(ApplianceCycle, a_camera_failing_mid_burst_is_an_error) {
    firmware::CycleSettings s;
    s.frames_per_capture = 3;
    Rig rig(prepared_dir("camera"),
            scenario_with("camera", "[faults]\ncamera_fails_at_capture = 3"), s);
    // Capture 1 is the camera check's single photo, 2 the target's metering frame, 3 its burst.
    rig.run_cycle();
    check_error_state(rig, "frame 2 of 3 never arrived");
}

TEST(ApplianceCycle, a_silent_printer_is_an_error) {
    Rig rig(prepared_dir("silent"), scenario_with("silent", "[faults]\nsilent_after_lines = 300"),
            {});
    rig.run_cycle();
    check_error_state(rig, "did not answer within 5 s");
}

TEST(ApplianceCycle, an_error_reply_is_an_error) {
    Rig rig(prepared_dir("halt"), scenario_with("halt", "[faults]\nerror_at_line = 300"), {});
    rig.run_cycle();
    check_error_state(rig, "Printer halted");
}

TEST(ApplianceCycle, a_resend_storm_is_an_error) {
    Rig rig(prepared_dir("storm"), scenario_with("storm", "[faults]\nline_noise = 0.7"), {});
    rig.run_cycle();
    check_error_state(rig, "too noisy");
}

TEST(ApplianceCycle, a_reset_mid_job_is_an_error) {
    Rig rig(prepared_dir("reset"), scenario_with("reset", "[faults]\nreset_at_line = 500"), {});
    rig.run_cycle();
    check_error_state(rig, "restarted mid-job");
}

TEST(ApplianceCycle, a_read_back_mismatch_restores_the_backup) {
    Rig rig(prepared_dir("readback"),
            scenario_with("readback", "[faults]\nsettings_ignored = true"), {});
    rig.run_cycle();
    const auto t = rig.transcript();
    // The last job put the backup back as M503 reported it (M666, then M665), then M500.
    CHECK(t.size() >= 4);
    STRCMP_EQUAL("M666 X0.000 Y0.000 Z0.000", command_of(t[t.size() - 3]).c_str());
    STRCMP_CONTAINS("M665 L250.000 R140.000", t[t.size() - 2].c_str());
    STRCMP_EQUAL("M500", command_of(t[t.size() - 1]).c_str());
    check_error_state(rig, "read-back mismatch: M665 L sent");
}

TEST(ApplianceCycle, a_correction_beyond_the_bounds_is_refused_and_never_sent) {
    Rig rig(prepared_dir("bounds"),
            scenario_with("bounds", "[limits]\nmax_rod_change_fraction = 0.001"), {});
    rig.run_cycle();
    for (const auto& line : rig.transcript()) CHECK(line.find("M665") == std::string::npos);
    check_error_state(rig, "solve: refused: the rod length would change");
}

// The twin as RepRapFirmware: its settings are asked for with M665 and M666 (its M503 lists
// config.g), set with one diagonal per tower, and read back from its own report format.
TEST(ApplianceCycle, a_reprapfirmware_printer_is_read_corrected_and_read_back_in_its_own_terms) {
    std::ifstream in(kScenario);
    std::stringstream text;
    text << in.rdbuf();
    std::string scenario = text.str();
    const std::string marlin = "firmware = \"marlin\"";
    scenario.replace(scenario.find(marlin), marlin.size(), "firmware = \"rrf\"");
    const fs::path path = fresh_dir("scenario_rrf") / "scenario.toml";
    std::ofstream(path) << scenario;
    Rig rig(prepared_dir("rrf"), path.string(), {});
    rig.run_cycle();
    rig.check_cycles_completed(1);
    const auto after = rig.board.bench->judge_delta_printer();
    UT_PRINT(("RepRapFirmware printer after the cycle: XY " + std::to_string(after.xy_rms) +
              " mm RMS, " + std::to_string(after.xy_max) + " mm worst")
                 .c_str());
    CHECK(after.xy_rms <= 0.002);  // the README's 0.0014 / 0.0032
    CHECK(after.xy_max <= 0.005);
    std::vector<std::string> commands;
    for (const auto& line : rig.transcript()) commands.push_back(command_of(line));
    CHECK(std::find(commands.begin(), commands.end(), "M503") == commands.end());
    // read, then per pass that sent something: back up, read back
    CHECK_EQUAL(3u, delta_of(rig.cycle).passes().size());
    CHECK_EQUAL(5, std::count(commands.begin(), commands.end(), "M665"));
    const auto& sent = delta_of(rig.cycle).solution()->commands;
    STRCMP_CONTAINS(":", sent[0].c_str());  // M665 L a:b:c
    CHECK(std::find(commands.begin(), commands.end(), sent[0]) != commands.end());
    const auto backup = rig.data.read_file("cycle-0001-backup.gcode");
    CHECK(backup.has_value());
    STRCMP_CONTAINS("M665 L250.000:250.000:250.000 R140.000", backup->c_str());
    STRCMP_CONTAINS("M666 X0.00 Y0.00 Z0.00", backup->c_str());
}

// After a completed cycle, revert puts back what the printer had, and reads it back; the box
// then starts from those settings again.
TEST(ApplianceCycle, revert_restores_the_backup_and_the_printer_reports_it) {
    Rig rig(prepared_dir("revert"), kScenario.string(), {});
    STRCMP_EQUAL("revert: no cycle has run here", rig.cycle.revert().c_str());
    const auto before = rig.board.bench->judge_delta_printer();
    rig.run_cycle();
    CHECK(rig.board.bench->judge_delta_printer().xy_rms <= 0.01);
    const std::size_t sent_by_cycle = rig.transcript().size();
    STRCMP_EQUAL("", rig.cycle.revert().c_str());
    rig.run_until([&] { return rig.ended == 2; });
    CHECK(rig.cycle.state() == firmware::CycleState::idle);
    // The printer is back where it was: the twin's truth says so, not the box.
    DOUBLES_EQUAL(before.xy_rms, rig.board.bench->judge_delta_printer().xy_rms, 1e-4);
    const auto t = rig.transcript();
    std::vector<std::string> revert_job;
    for (std::size_t i = sent_by_cycle; i < t.size(); ++i) revert_job.push_back(command_of(t[i]));
    CHECK(revert_job == (std::vector<std::string>{
                            "M110 N0", "M666 X0.000 Y0.000 Z0.000",
                            "M665 L250.000 R140.000 H300.107 X0.000 Y0.000 Z0.000 A0.000 B0.000 "
                            "C0.000",
                            "M500", "M110 N0", "M503"}));
    // The printer stored it (M500): a power cycle of the twin keeps it.
    std::ifstream stored(rig.dir / sim::kTwinSettingsFile);
    std::stringstream stored_text;
    stored_text << stored.rdbuf();
    STRCMP_CONTAINS("M665 L250.000 R140.000 H300.107", stored_text.str().c_str());
}

// The twin printer keeps what it stored across runs of the box, as an EEPROM does: settings
// stored (M500) in one run are in force at the next; settings not stored are not.
TEST(ApplianceCycle, the_twin_printer_keeps_its_stored_settings_across_runs) {
    const fs::path dir = fresh_dir("eeprom");
    const auto run_job = [](Rig& rig, const std::vector<std::string>& lines) {
        std::optional<firmware::JobOutcome> outcome;
        rig.host.start_job(lines, [&](firmware::JobOutcome o) { outcome = std::move(o); });
        rig.run_until([&] { return outcome.has_value(); });
        CHECK_TEXT(outcome->ok, outcome->error.c_str());
        return outcome->replies;
    };
    {
        Rig rig(dir, kScenario.string(), {});
        run_job(rig, {"M665 L251.5 R140.25", "M500", "M665 L252"});
    }
    Rig again(dir, kScenario.string(), {});
    const auto replies = run_job(again, {"M503"});
    CHECK(std::any_of(replies.begin(), replies.end(), [](const std::string& r) {
        return r.find("M665 L251.500 R140.250") != std::string::npos;
    }));
}
