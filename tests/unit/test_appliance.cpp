// The appliance on the sim board: the cycle driven through the event loop on simulated time, the
// twin printer behind a real pty (termios driver, host protocol), the rendering camera; each
// fault the scenario can inject ends in the error state with one message, the error LED, nothing
// more sent to the printer, and idle again after a press. The twin judges the printer in its
// truth; the box never reads it.
#include <CppUTest/TestHarness.h>
#include <CppUTestExt/MockSupport.h>
#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>

#include "board/sim/twin_judge.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/modes/galvo.hpp"
#include "core/number_text.hpp"
#include "drivers/file_camera.hpp"
#include "drivers/file_storage.hpp"
#include "firmware/app/box_config.hpp"
#include "firmware/app/sim_appliance.hpp"
#include "firmware/app/sim_operator.hpp"
#include "firmware/console/console.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/links/gcode_host.hpp"
#include "firmware/loop/event_loop.hpp"
#include "firmware/modes/delta_mode.hpp"
#include "firmware/modes/galvo_mode.hpp"
#include "firmware/net/box_news.hpp"
#include "firmware/plc/plc_link.hpp"
#include "tests/support/device_errors.hpp"
#include "tests/support/fake_clock.hpp"

using namespace calbox;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

namespace {

// A delta printer's cycle: its passes and the correction sent.
const firmware::DeltaCycleMode& delta_of(const firmware::Cycle& cycle) {
    return dynamic_cast<const firmware::DeltaCycleMode&>(cycle.mode());
}

const fs::path kScenario = fs::path(CALBOX_SOURCE_DIR) / "tests/scenarios/delta_cycle_small.toml";

// A fresh directory in the temporary area, one set per process (ctest runs the groups side by
// side and each builds its own set-up), all removed when the process ends.
fs::path fresh_dir(const std::string& name) {
    static const struct Cleanup {
        fs::path root =
            fs::temp_directory_path() / ("calbox_test_appliance_" + std::to_string(::getpid()));
        ~Cleanup() {
            std::error_code ignored;
            fs::remove_all(root, ignored);
        }
    } cleanup;
    const fs::path dir = cleanup.root / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

// The small scenario with extra TOML (faults) appended, as a file.
std::string scenario_with(const std::string& name, const std::string& extra) {
    std::ifstream in(kScenario);
    std::stringstream text;
    text << in.rdbuf() << "\n" << extra << "\n";
    const fs::path path = fresh_dir("scenario_" + name) / "scenario.toml";
    std::ofstream(path) << text.str();
    return path.string();
}

// Everything calbox run wires together, on a fake clock.
struct Rig {
    fs::path dir;
    test::FakeClock clock;
    std::vector<std::string> log;
    firmware::SimAppliance box;
    sim::SimBoard& board = box.board;
    hal::Storage& data = box.data;
    firmware::EventLoop& loop = box.loop;
    firmware::Worker& worker = box.worker;
    firmware::GcodeHost& host = box.host();
    firmware::Cycle& cycle = box.cycle;
    bool operator_acts = true;
    std::function<bool(firmware::Prompt)> intercept;  // true: the test handled the prompt
    int ended = 0;
    firmware::CycleSubscription listening;

    Rig(const fs::path& data_dir, const std::string& scenario, firmware::CycleSettings settings,
        const firmware::SimAppliance::CameraChoice& choose_camera = {},
        drivers::FileSystemCalls& data_files = drivers::posix_file_system())
        : dir(data_dir),
          box(
              {scenario, data_dir, 115200}, clock, {1, 5000ms, 8}, std::move(settings),
              [this](const std::string& l) { log.push_back(l); }, choose_camera,
              std::make_unique<drivers::FileStorage>(data_dir, data_files)) {
        listening =
            cycle.subscribe({[this](firmware::Prompt p, int step) {
                                 if (intercept && intercept(p)) return;
                                 if (operator_acts)
                                     firmware::act_on_prompt(*board.bench, *board.lines, p, step);
                             },
                             {},
                             [this](bool) { ++ended; },
                             {},
                             {}});
        // The twin's start-up banner, in real time: the fake clock must not run past the host's
        // wait for it while the printer's thread is still starting.
        if (!sim::start_up_banner(board.machine).empty()) {
            for (int i = 0; i < 250 && !host.heard_from_printer(); ++i) loop.run_once(20ms);
            CHECK_TEXT(host.heard_from_printer(), "the twin printer sent no start-up banner");
        }
    }

    // Runs the loop until `done`; when nothing is ready, simulated time moves on by a second (so
    // the printer's silence times out without real waiting), but only once the twin printer has
    // answered all it was sent: under load its thread can take longer than the loop's 20 ms.
    void run_until(const std::function<bool()>& done, int max_iterations = 200000) {
        for (int i = 0; i < max_iterations && !done(); ++i)
            if (loop.run_once(20ms) == 0 && !worker.busy() && !camera_busy() && printer_settled())
                clock.advance(1s);
        CHECK_TEXT(done(), ("the loop did not get there; last log: " +
                            (log.empty() ? std::string() : log.back()))
                               .c_str());
    }
    // The twin has read every line the box wrote (a pty can hold written bytes back from the
    // reader for a while on a loaded machine) and answered it.
    bool printer_settled() const {
        return !board.printer || (board.printer->lines_received() >= host.lines_written() &&
                                  board.printer->settled());
    }
    // A photo being rendered: simulated time waits for it (a prompt is a person, not the camera).
    bool camera_busy() const {
        if (cycle.prompt() != firmware::Prompt::none) return false;
        return cycle.state() == firmware::CycleState::capture ||
               cycle.state() == firmware::CycleState::setup_camera ||
               cycle.state() == firmware::CycleState::setup_plane;
    }
    // Until the cycle has left idle, or has already come back to it (cancelled at once).
    void start() {
        const int ended_before = ended;
        board.lines->press(100ms);
        run_until([this, ended_before] {
            return cycle.state() != firmware::CycleState::idle || ended > ended_before;
        });
    }
    void run_cycle() {
        start();
        run_until([this] { return ended > 0; });
    }
    // With the box's last log line when not: a cycle that ended in its error state says why.
    void check_cycles_completed(int expected) const {
        CHECK_EQUAL_TEXT(expected, cycle.cycles_completed(),
                         ("last log: " + (log.empty() ? std::string() : log.back())).c_str());
    }
    std::vector<std::string> transcript() const {
        return {host.transcript().begin(), host.transcript().end()};
    }
    // Nothing more goes to the printer: the loop runs on for `seconds` of simulated time.
    void check_nothing_more_sent(int seconds) {
        const std::size_t sent = transcript().size();
        for (int i = 0; i < seconds; ++i) {
            loop.run_once(5ms);
            clock.advance(1s);
        }
        CHECK_EQUAL(sent, transcript().size());
    }
};

// The set-up (camera from 12 board views, plane from a board on the bed), done once through the
// cycle itself (cancelled at the first print's prompt) and copied into each test's directory.
const fs::path& prepared_setup() {
    static const fs::path dir = [] {
        const fs::path d = fresh_dir("setup");
        Rig rig(d, kScenario.string(), {});
        rig.intercept = [&rig](firmware::Prompt p) {
            if (p != firmware::Prompt::clear_bed) return false;
            rig.board.lines->press(2000ms);  // long press: cancel
            return true;
        };
        rig.run_cycle();
        return d;
    }();
    return dir;
}

fs::path prepared_dir(const std::string& name) {
    const fs::path d = fresh_dir(name);
    for (const char* f : {"camera.yaml", "plane.yaml", firmware::kReferenceFile})
        fs::copy_file(prepared_setup() / f, d / f);
    return d;
}

// XOR of the bytes before '*', worked here rather than by the code under test.
bool checksum_holds(const std::string& line) {
    const auto star = line.find('*');
    if (star == std::string::npos) return false;
    unsigned sum = 0;
    for (std::size_t i = 0; i < star; ++i) sum ^= static_cast<unsigned char>(line[i]);
    return std::to_string(sum) == line.substr(star + 1);
}

// The command of "N12 G1 X1*34": "G1 X1".
std::string command_of(const std::string& line) {
    const auto space = line.find(' ');
    return line.substr(space + 1, line.find('*') - space - 1);
}

// The transcript as jobs, each opened by N0 M110 N0, its lines numbered on from 1, every
// checksum right: each job's commands.
std::vector<std::vector<std::string>> jobs_of(const std::vector<std::string>& transcript) {
    std::vector<std::vector<std::string>> jobs;
    for (const auto& line : transcript) {
        CHECK_TEXT(checksum_holds(line), line.c_str());
        if (line == "N0 M110 N0*125") {
            jobs.emplace_back();
            continue;
        }
        CHECK(!jobs.empty());
        CHECK_EQUAL(std::to_string(jobs.back().size() + 1), line.substr(1, line.find(' ') - 1));
        CHECK_EQUAL('N', line[0]);
        jobs.back().push_back(command_of(line));
    }
    return jobs;
}

void check_error_state(Rig& rig, const char* message_part) {
    CHECK(rig.cycle.state() == firmware::CycleState::error);
    STRCMP_CONTAINS(message_part, rig.cycle.error().c_str());
    CHECK(rig.board.lines->led(hal::Led::error));
    CHECK_FALSE(rig.board.lines->light());
    rig.check_nothing_more_sent(50);
    rig.board.lines->press(100ms);
    rig.run_until([&] { return rig.cycle.state() == firmware::CycleState::idle; });
    CHECK_FALSE(rig.board.lines->led(hal::Led::error));
    UT_PRINT(("error state: " + rig.cycle.error()).c_str());
}

}  // namespace

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

TEST_GROUP(ApplianceLink){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

// The twin's banner goes out as soon as anyone opens the line; a line the box has opened but
// not yet made raw must not echo it back to the printer as a G-code line.
TEST(ApplianceLink, the_printers_banner_is_not_echoed_back_before_the_line_is_raw) {
    auto bench = std::make_shared<sim::TwinBench>(sim::load_scenario(kScenario.string()));
    sim::TwinPrinterLink link(bench);
    const int slave = ::open(link.device_path().c_str(), O_RDWR | O_NOCTTY);
    CHECK(slave >= 0);
    char banner[64] = {};
    std::size_t got = 0;
    for (int i = 0; i < 100 && got < 6; ++i) {
        pollfd p{slave, POLLIN, 0};
        if (::poll(&p, 1, 20) == 1) {
            const ssize_t n = ::read(slave, banner + got, sizeof banner - 1 - got);
            if (n > 0) got += static_cast<std::size_t>(n);
        }
    }
    STRCMP_CONTAINS("start", banner);
    ::usleep(200000);  // the printer's thread has read whatever came back by now
    CHECK_EQUAL(0u, link.lines_received());
    ::close(slave);
}

// The twin as grbl: its own welcome, not Marlin's; a numbered, checksummed line is its error:1
// (a word without its letter), M110 its error:20, a plain line an ok; a move beyond the travel
// its soft-limit alarm, after which it is locked (error:9).
TEST(ApplianceLink, a_grbl_twin_greets_and_answers_as_grbl) {
    auto bench = std::make_shared<sim::TwinBench>(sim::load_scenario(
        (fs::path(CALBOX_SOURCE_DIR) / "tests/scenarios/planar_small.toml").string()));
    sim::TwinPrinterLink link(bench);
    const int slave = ::open(link.device_path().c_str(), O_RDWR | O_NOCTTY);
    CHECK(slave >= 0);
    termios raw{};
    ::tcgetattr(slave, &raw);
    ::cfmakeraw(&raw);
    ::tcsetattr(slave, TCSANOW, &raw);
    std::string heard;
    const auto hear_line = [&] {
        for (int i = 0; i < 200 && heard.find('\n') == std::string::npos; ++i) {
            pollfd p{slave, POLLIN, 0};
            char buffer[256];
            if (::poll(&p, 1, 20) == 1) {
                const ssize_t n = ::read(slave, buffer, sizeof buffer);
                if (n > 0) heard.append(buffer, static_cast<std::size_t>(n));
            }
        }
        const auto end = heard.find('\n');
        const std::string line = heard.substr(0, end);
        heard.erase(0, end == std::string::npos ? heard.size() : end + 1);
        return line;
    };
    const auto say = [&](const std::string& line) {
        const std::string text = line + "\n";
        CHECK_EQUAL(static_cast<ssize_t>(text.size()), ::write(slave, text.data(), text.size()));
        return hear_line();
    };
    STRCMP_EQUAL("Grbl 1.1h ['$' for help]", hear_line().c_str());
    STRCMP_EQUAL("error:1", say("N1 G21*19").c_str());
    STRCMP_EQUAL("error:20", say("M110 N0").c_str());
    STRCMP_EQUAL("ok", say("G21").c_str());
    STRCMP_EQUAL("ALARM:2", say("G0 X5000 Y0").c_str());
    STRCMP_EQUAL("error:9", say("G21").c_str());
    ::close(slave);
}

// Line noise on the pty: the printer refuses corrupted lines, the box resends, the cycle ends
// as on a clean link.
TEST(ApplianceLink, a_noisy_link_is_resent_line_by_line_and_the_cycle_completes) {
    Rig rig(prepared_dir("noise"), scenario_with("noise", "[faults]\nline_noise = 0.05"), {});
    rig.run_cycle();
    rig.check_cycles_completed(1);
    std::size_t resent = 0;
    const auto t = rig.transcript();
    for (std::size_t i = 1; i < t.size(); ++i)
        if (t[i] == t[i - 1]) ++resent;
    UT_PRINT(
        ("lines resent after noise: " + std::to_string(resent) + " of " + std::to_string(t.size()))
            .c_str());
    CHECK(resent > 50);
    const auto after = rig.board.bench->judge_delta_printer();
    CHECK(after.xy_rms <= 0.01);
}

// From an empty data directory: the set-up asks for the board views and the plane first.
TEST(ApplianceLink, the_first_cycle_runs_the_set_up_from_photos) {
    const fs::path& dir = prepared_setup();
    CHECK(fs::exists(dir / "camera.yaml"));
    std::ifstream camera(dir / "camera.yaml");
    std::stringstream text;
    text << camera.rdbuf();
    STRCMP_CONTAINS("camera_matrix", text.str().c_str());
}

// The twin's camera, each frame it gives also saved as the next numbered PNG.
struct RecordingCamera final : hal::Camera {
    hal::Camera* twin = nullptr;
    fs::path dir;
    int saved = 0;
    void start_capture(const hal::CaptureRequest& request) override {
        twin->start_capture(request);
    }
    int completion_fd() const override { return twin->completion_fd(); }
    hal::CaptureResult take_frames() override {
        auto result = twin->take_frames();
        for (const auto& frame : result.frames) {
            char name[16];
            std::snprintf(name, sizeof name, "%04d.png", ++saved);
            drivers::write_frame_png(dir / name, frame);
        }
        return result;
    }
};

TEST_GROUP(ApplianceFiles){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

// A cycle re-run on the photos a first cycle saved (--camera-files): the same measurements, so
// the same correction and verification, and the second twin printer, which never showed its
// print to a camera, ends as well calibrated as the first.
TEST(ApplianceFiles, a_cycle_runs_whole_on_saved_photos) {
    const fs::path photos = fresh_dir("photos");
    RecordingCamera recorder;
    recorder.dir = photos;
    std::optional<std::vector<std::string>> first_commands;
    std::optional<double> first_verify;
    {
        Rig first(prepared_dir("files_first"), kScenario.string(), {},
                  [&recorder](sim::SimBoard& board) -> hal::Camera& {
                      recorder.twin = board.camera;
                      return recorder;
                  });
        first.run_cycle();
        first.check_cycles_completed(1);
        first_commands = delta_of(first.cycle).solution()->commands;
        first_verify = first.cycle.report().verified->rms_mm;
    }
    // the camera check, the target, the verification prints of the two passes that sent something
    CHECK_EQUAL(4, recorder.saved);

    drivers::FileCamera files(photos.string());
    auto use_files = [&files](sim::SimBoard&) -> hal::Camera& { return files; };
    Rig second(prepared_dir("files_second"), kScenario.string(), {}, use_files);
    second.run_cycle();
    second.check_cycles_completed(1);
    CHECK_EQUAL(0, second.board.camera->captures_started());  // the twin's camera never used
    // Photos from files say nothing of their exposure: not metered, and said.
    CHECK(std::any_of(second.log.begin(), second.log.end(), [](const std::string& line) {
        return line.find("target: exposure the camera's own; ") != std::string::npos &&
               line.find("the camera does not report its exposure: taken at its own") !=
                   std::string::npos;
    }));
    CHECK(delta_of(second.cycle).solution()->commands == *first_commands);
    DOUBLES_EQUAL(*first_verify, second.cycle.report().verified->rms_mm, 1e-12);
    const auto after = second.board.bench->judge_delta_printer();
    CHECK(after.xy_rms <= 0.0045);
    CHECK(after.xy_max <= 0.0105);
}

TEST(ApplianceFiles, photos_of_another_size_than_the_calibration_stop_with_one_line) {
    const fs::path photos = fresh_dir("small_photos");
    hal::Frame small;
    small.width_px = 640;
    small.height_px = 480;
    small.stride_bytes = 640;
    small.pixels.assign(640 * 480, 128);
    drivers::write_frame_png(photos / "0001.png", small);
    drivers::FileCamera files(photos.string());
    Rig rig(prepared_dir("files_small"), kScenario.string(), {},
            [&files](sim::SimBoard&) -> hal::Camera& { return files; });
    rig.run_cycle();
    CHECK(rig.cycle.state() == firmware::CycleState::error);
    STRCMP_CONTAINS("the photo is 640x480, the camera was calibrated at 2028x1520 (camera.yaml)",
                    rig.cycle.error().c_str());
}

TEST(ApplianceFiles, a_source_without_photos_and_photos_running_out_are_errors) {
    const fs::path empty = fresh_dir("no_photos");
    CHECK_THROWS(std::runtime_error, drivers::FileCamera(empty.string()));
    const fs::path one = fresh_dir("one_photo");
    hal::Frame frame;
    frame.width_px = 8;
    frame.height_px = 4;
    frame.stride_bytes = 8;
    frame.pixels.assign(32, 7);
    drivers::write_frame_png(one / "a.png", frame);
    drivers::FileCamera files((one / "*.png").string());
    files.start_capture({2, {}, {}});
    pollfd p{files.completion_fd(), POLLIN, 0};
    CHECK_EQUAL(1, ::poll(&p, 1, 5000));
    const auto result = files.take_frames();
    STRCMP_CONTAINS("no photo left (all 1 used)", result.error.c_str());

    // A photo the box's user may not read (mode 0600, owned by root): one line, naming it.
    fs::permissions(one / "a.png", fs::perms::owner_read | fs::perms::owner_write);
    const std::string denied = test::error_as_unprivileged_user([&] {
        drivers::FileCamera mine(one.string());
        mine.start_capture({1, {}, {}});
        pollfd q{mine.completion_fd(), POLLIN, 0};
        ::poll(&q, 1, 5000);
        throw std::runtime_error(mine.take_frames().error);
    });
    STRCMP_CONTAINS(((one / "a.png").string() + ": cannot read: Permission denied").c_str(),
                    denied.c_str());
}

// A galvo scanner under the box (issue 17): the grid burned over the link, measured, the table
// kept by the box, the grid burned through it to verify, and revert putting the previous (no)
// table back. Half-size camera; the set-up from photos as on a real box.
// The data directory's disk, filling up when the test says: every write then fails as a full
// disk's does (ENOSPC), after part of the bytes went in.
struct FillingDisk final : drivers::FileSystemCalls {
    bool full = false;
    drivers::FileSystemCalls& real = drivers::posix_file_system();
    int create_truncated(const fs::path& p, drivers::FileAccess access) override {
        return real.create_truncated(p, access);
    }
    void write_all(int h, std::string_view bytes) override {
        if (!full) return real.write_all(h, bytes);
        real.write_all(h, bytes.substr(0, bytes.size() / 2));
        errno = ENOSPC;
        throw std::runtime_error("cannot write " + std::to_string(h) + ": " + std::strerror(errno));
    }
    void flush(int h) override { real.flush(h); }
    void close(int h) override { real.close(h); }
    void rename(const fs::path& a, const fs::path& b) override { real.rename(a, b); }
    void flush_directory(const fs::path& d) override { real.flush_directory(d); }
    void remove(const fs::path& p) noexcept override { real.remove(p); }
};

TEST(ApplianceFiles, a_full_disk_stops_the_cycle_with_nothing_half_written_and_nothing_sent) {
    FillingDisk disk;
    Rig rig(prepared_dir("full_disk"), kScenario.string(), {}, {}, disk);
    const auto before = rig.board.bench->judge_delta_printer();
    disk.full = true;
    rig.run_cycle();
    CHECK(rig.cycle.state() == firmware::CycleState::error);
    STRCMP_CONTAINS("records: cannot write", rig.cycle.error().c_str());
    STRCMP_CONTAINS("No space left on device", rig.cycle.error().c_str());
    for (const auto& line : rig.transcript()) {
        CHECK_TEXT(command_of(line).rfind("M665", 0) != 0 && command_of(line).rfind("M500", 0) != 0,
                   ("sent with a full disk: " + line).c_str());
    }
    for (const auto& entry : fs::directory_iterator(rig.dir)) {
        const auto name = entry.path().filename().string();
        CHECK_TEXT(name.find(".tmp") == std::string::npos, ("left behind: " + name).c_str());
        CHECK_TEXT(name.rfind("cycle-0001-", 0) != 0, ("half a record: " + name).c_str());
    }
    const auto after = rig.board.bench->judge_delta_printer();
    DOUBLES_EQUAL(before.xy_rms, after.xy_rms, 1e-12);  // the printer's geometry as it was
    check_error_state(rig, "No space left on device");
}

// A cycle's record: measurements, result, backup, its photos (records.keep_photos) and every
// display frame it showed; older records pruned past the count, then past the size.
TEST(ApplianceFiles, each_cycle_leaves_a_record_and_old_ones_are_pruned) {
    const fs::path dir = prepared_dir("records");
    for (int n : {1, 2, 3}) {
        char name[40];
        std::snprintf(name, sizeof name, "cycle-%04d-result.json", n);
        std::ofstream(dir / name) << "{}\n";
    }
    fs::resize_file(dir / "cycle-0002-result.json", 50'000'000);  // sparse: 50 MB on paper
    std::ofstream(dir / "last-cycle") << "3\n";
    std::ofstream(dir / "cycle-notes.txt") << "not a record\n";
    firmware::CycleSettings settings;
    settings.records = {3, 30'000'000, true};
    Rig rig(dir, kScenario.string(), settings);
    rig.run_cycle();
    rig.check_cycles_completed(1);
    CHECK_EQUAL(4, rig.cycle.report().number);
    std::uintmax_t newest_bytes = 0;
    int screens = 0;
    for (const auto& entry : fs::directory_iterator(dir)) {
        const auto name = entry.path().filename().string();
        if (name.rfind("cycle-0004-", 0) == 0) newest_bytes += entry.file_size();
        if (name.rfind("cycle-0004-screen-", 0) == 0) ++screens;
    }
    UT_PRINT(("the newest record: " + std::to_string(newest_bytes) + " bytes").c_str());
    CHECK_TEXT(newest_bytes < 25'000'000, "the newest record alone is too big for this test");
    CHECK_FALSE(fs::exists(dir / "cycle-0001-result.json"));  // past the count of 3
    CHECK_FALSE(fs::exists(dir / "cycle-0002-result.json"));  // past 30 MB
    CHECK_TRUE(fs::exists(dir / "cycle-0003-result.json"));
    CHECK_TRUE(fs::exists(dir / "cycle-notes.txt"));
    for (const char* f :
         {"measurements.json", "result.json", "backup.gcode", "verify-measurements.json",
          "target-photo-1.png", "verify-photo-1.png", "overlay.png", "verify-overlay.png",
          "pass-2-result.json", "pass-2-backup.gcode", "pass-2-verify-measurements.json",
          "pass-2-verify-photo-1.png", "pass-2-verify-overlay.png", "error-field.png",
          "pass-2-error-field.png"})
        CHECK_TEXT(fs::exists(dir / ("cycle-0004-" + std::string(f))), f);
    const cv::Mat photo =
        cv::imread((dir / "cycle-0004-target-photo-1.png").string(), cv::IMREAD_UNCHANGED);
    CHECK_EQUAL(2028, photo.cols);
    CHECK_EQUAL(1520, photo.rows);
    CHECK_EQUAL(CV_8UC1, photo.type());
    const cv::Mat overlay = cv::imread((dir / "cycle-0004-overlay.png").string(), cv::IMREAD_COLOR);
    CHECK_EQUAL(2028, overlay.cols);  // drawn on the first photo
    // Every frame the display showed from the start to the done screen.
    CHECK_TRUE(screens >= 10);
    const cv::Mat last_screen =
        cv::imread((dir / ("cycle-0004-screen-" + std::string(screens < 10 ? "0" : "") +
                           std::to_string(screens) + ".png"))
                       .string(),
                   cv::IMREAD_GRAYSCALE);
    CHECK_EQUAL(128, last_screen.cols);
    CHECK_EQUAL(64, last_screen.rows);
}

TEST_GROUP(ApplianceGalvo){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

TEST(ApplianceGalvo, a_scanner_is_corrected_through_the_boxs_table_and_reverted) {
    const fs::path dir = fresh_dir("galvo");
    Rig rig(dir, (fs::path(CALBOX_SOURCE_DIR) / "tests/scenarios/galvo_small.toml").string(), {});
    const auto identity = [](sim::Vec2 p) { return p; };
    const double half = 55.0 * 30 / 31;
    const auto before = rig.board.bench->judge_galvo_scanner(identity, {-half, -half, half, half});
    rig.run_cycle();
    rig.check_cycles_completed(1);
    const auto& report = rig.cycle.report();
    const auto* galvo = dynamic_cast<const firmware::GalvoCycleMode*>(&rig.cycle.mode());
    CHECK(galvo != nullptr && galvo->solution().has_value());
    CHECK(report.applied);
    // The box's own figures: the grid as burned, and through the table.
    CHECK(report.measured->rms_mm > 0.05);
    CHECK_TEXT(report.verified->rms_mm <= 0.004, std::to_string(report.verified->rms_mm).c_str());
    CHECK(report.verified->max_mm <= 0.015);
    // What the review promised is what the verification then measured, within a factor of 1.5
    // either way (it once promised 0.0001 mm RMS, a seventh of the 0.0007 measured).
    const double predicted = galvo->solution()->predicted_rms_mm;
    UT_PRINT(("galvo review predicted " + std::to_string(predicted) + " mm RMS, verified " +
              std::to_string(report.verified->rms_mm))
                 .c_str());
    CHECK(predicted <= 1.5 * report.verified->rms_mm);
    CHECK(report.verified->rms_mm <= 1.5 * predicted);
    // The twin judges the table the box keeps, on a fresh grid.
    const auto kept = rig.data.read_file(firmware::kGalvoTableFile);
    CHECK(kept.has_value());
    // The file the web page serves with the records is the one the table is kept in.
    CHECK(rig.cycle.mode().kept_files() == std::vector<std::string>{firmware::kGalvoTableFile});
    // What a controller reads over Modbus: that table, under the key a map file moves it by, in
    // as many registers as the mode declares (the PLC's map checks overlaps with that count).
    const auto for_controller = rig.cycle.mode().result(true);
    CHECK_EQUAL(firmware::GalvoCycleMode::result_table().key, for_controller.table_key);
    CHECK_EQUAL(firmware::GalvoCycleMode::result_table().registers,
                2 * static_cast<int>(for_controller.table.size()));
    const auto table = modes::galvo_result_from_json(*kept, "kept").fit.table;
    const auto after = rig.board.bench->judge_galvo_scanner(
        [&table](sim::Vec2 p) {
            const auto c = table.command_for({p.x, p.y});
            return sim::Vec2{c.x, c.y};
        },
        {table.min_x_mm, table.min_y_mm, table.max_x_mm, table.max_y_mm});
    UT_PRINT(("galvo on the box: before " + std::to_string(before.mean_mm) + " mm mean, after " +
              std::to_string(after.mean_mm) + " mean " + std::to_string(after.max_mm) +
              " worst; the box verified " + std::to_string(report.verified->rms_mm) + " RMS")
                 .c_str());
    // The goal is 0.008 mean and 0.03 worst; the README claims 0.002 and 0.008.
    CHECK(before.mean_mm > 0.05);
    CHECK(after.mean_mm <= 0.002);
    CHECK(after.max_mm <= 0.008);
    // Two jobs went: the grid, then the grid through the table: the same lines but the moves.
    const auto sent = rig.transcript();
    const auto count = [&sent](const std::string& word) {
        return std::count_if(sent.begin(), sent.end(), [&word](const std::string& l) {
            return l.find(word) != std::string::npos;
        });
    };
    // grbl's plain lines: each job opens with its own G21, nothing numbered or checksummed.
    CHECK_EQUAL(2, std::count(sent.begin(), sent.end(), "G21"));
    CHECK_EQUAL(0, count("M110"));
    CHECK_EQUAL(0, count("*"));
    CHECK(count("M3 S") > 1900);    // every mark's beam switched on, twice
    CHECK_EQUAL(0, count("M665"));  // a galvo's geometry is not a printer's settings
    CHECK(rig.data.read_file("cycle-0001-table.csv").has_value());
    const auto verified = modes::galvo_result_from_json(
        *rig.data.read_file("cycle-0001-verify-result.json"), "verify-result.json");
    CHECK_EQUAL(2, verified.pass);
    DOUBLES_EQUAL(report.verified->rms_mm, verified.fit.before.rms_mm, 1e-12);
    CHECK_EQUAL(std::string(firmware::kNoGalvoTable),
                *rig.data.read_file("cycle-0001-backup-table.json"));

    // Issue "Figures and drawings that mean what they say": a second cycle on the scanner as its
    // table left it reads no drift and no need, though the raw grid is as far off as ever (the
    // box once compared that raw error with the error verified through the table). Its owner
    // only looks: cancelled at review, nothing sent.
    firmware::BoxNews news(rig.data, "test", {});
    news.cycle_ended(rig.cycle, true, 1'700'000'000);
    const auto told = rig.cycle.subscribe(
        {{},
         {},
         [&](bool completed) { news.cycle_ended(rig.cycle, completed, 1'700'000'600); },
         {},
         {}});
    // The owner only looks: each cycle below is cancelled at review (a long press).
    const auto cancel_at_review = [&rig](firmware::Prompt p) {
        if (p != firmware::Prompt::review) return false;
        rig.board.lines->press(2000ms);
        return true;
    };
    rig.intercept = cancel_at_review;
    rig.ended = 0;
    rig.run_cycle();
    rig.intercept = nullptr;
    rig.check_cycles_completed(1);
    const auto& again = rig.cycle.report();
    UT_PRINT(("galvo, second cycle: raw " + number_text("%.4f", *again.measured->mean_mm) +
              " mm mean, through the table " + number_text("%.4f", *again.in_force->mean_mm) +
              " (the twin's truth " + number_text("%.4f", after.mean_mm) + "), drift " +
              number_text("%.4f", news.drift_mm().value_or(-1)))
                 .c_str());
    CHECK(*again.measured->mean_mm > 0.05);
    CHECK(std::abs(*again.in_force->mean_mm - after.mean_mm) < 0.002);
    CHECK(std::abs(*news.drift_mm()) < 0.003);
    CHECK_FALSE(*news.needs_calibration());
    CHECK_EQUAL(*kept, *rig.data.read_file(firmware::kGalvoTableFile));  // nothing applied

    // Then the x mirror's gain drifts by 0.1 % (0.055 mm at the field's edges): a third cycle,
    // again only looked at, reads that as drift, as the twin's truth has it through the table.
    // (A head turned on its mount moves the whole field, which each measurement places anew.)
    rig.board.bench->change_machine([](sim::Scenario& s) { s.galvo_truth.gain_x += 0.001; });
    const auto changed = rig.board.bench->judge_galvo_scanner(
        [&table](sim::Vec2 p) {
            const auto c = table.command_for({p.x, p.y});
            return sim::Vec2{c.x, c.y};
        },
        {table.min_x_mm, table.min_y_mm, table.max_x_mm, table.max_y_mm});
    rig.intercept = cancel_at_review;
    rig.ended = 0;
    rig.run_cycle();
    rig.intercept = nullptr;
    rig.check_cycles_completed(1);
    UT_PRINT(("galvo, third cycle (gain drifted): through the table " +
              number_text("%.4f", *rig.cycle.report().in_force->mean_mm) + " (the twin's truth " +
              number_text("%.4f", changed.mean_mm) + "), drift " +
              number_text("%.4f", news.drift_mm().value_or(-1)))
                 .c_str());
    CHECK(changed.mean_mm > 0.015);
    CHECK(std::abs(*rig.cycle.report().in_force->mean_mm - changed.mean_mm) < 0.005);
    CHECK(std::abs(*news.drift_mm() - changed.mean_mm) < 0.005);

    // Revert puts back what was in force before: no table.
    const std::size_t sent_before_revert = rig.transcript().size();
    CHECK_EQUAL(std::string(), rig.cycle.revert());
    rig.run_until([&rig] { return rig.cycle.state() == firmware::CycleState::idle; });
    CHECK_EQUAL(std::string(firmware::kNoGalvoTable),
                *rig.data.read_file(firmware::kGalvoTableFile));
    CHECK_EQUAL(sent_before_revert, rig.transcript().size());
}

// Issue "One shape for every mode": the PLC's pass bit is each mode's own goal on the box's own
// verification, not the delta goal for every machine.
namespace {

// The box's registers as a PLC would read them.
class PlcRegisters final : public hal::RegisterServer {
  public:
    std::vector<bool> inputs = std::vector<bool>(firmware::plc::kDiscreteInputCount, false);
    std::map<int, std::uint16_t> registers;
    int written_fd() const override { return -1; }
    std::vector<int> take_coils_set() override { return {}; }
    void set_discrete_inputs(int first, const std::vector<bool>& values) override {
        for (std::size_t i = 0; i < values.size(); ++i)
            inputs.at(static_cast<std::size_t>(first) + i) = values[i];
    }
    void set_input_registers(int first, std::span<const std::uint16_t> values) override {
        for (std::size_t i = 0; i < values.size(); ++i)
            registers[first + static_cast<int>(i)] = values[i];
    }
    double result(const std::string& name) const {
        const auto& names = firmware::result_value_names();
        const auto at = std::find(names.begin(), names.end(), name) - names.begin();
        const int address = firmware::plc::kResultBlockRegister + 2 * static_cast<int>(at);
        return models::unpack_float({registers.at(address), registers.at(address + 1)},
                                    models::WordOrder::abcd);
    }
};

struct PlcRig {
    Rig rig;
    PlcRegisters registers;
    firmware::PlcServer plc{registers, rig.cycle, models::WordOrder::abcd,
                            [](const std::string&) {}};
    explicit PlcRig(const std::string& scenario)
        : rig(fresh_dir("plc-" + fs::path(scenario).stem().string()),
              (fs::path(CALBOX_SOURCE_DIR) / scenario).string(), {}) {
        rig.run_cycle();
        rig.check_cycles_completed(1);
        plc.publish();
        CHECK(registers.inputs[firmware::plc::kDoneInput]);
    }
};

}  // namespace

TEST_GROUP(AppliancePlc){void setup() override{mock().ignoreOtherCalls();
}
}
;

// The router's own figures: 0.025 mm mean (0.027 RMS, 0.065 worst) through the model, from 1.23
// before: under 0.05 and 98 % less. The delta goal (RMS <= 0.01) would have read fail.
TEST(AppliancePlc, a_router_meeting_its_goal_reads_pass) {
    PlcRig r("tests/scenarios/planar_small.toml");
    const auto& report = r.rig.cycle.report();
    UT_PRINT(("router verified " + std::to_string(*report.verified->mean_mm) + " mm mean, " +
              std::to_string(report.verified->rms_mm) + " RMS, from " +
              std::to_string(*report.measured->mean_mm))
                 .c_str());
    CHECK(*report.verified->mean_mm < 0.05);
    CHECK(*report.verified->mean_mm < 0.05 * *report.measured->mean_mm);
    CHECK(report.verified->rms_mm > 0.01);
    CHECK(r.registers.inputs[firmware::plc::kPassInput]);
    CHECK(r.rig.cycle.goal_met());
    DOUBLES_EQUAL(report.verified->rms_mm, r.registers.result("verified_xy_rms_mm"), 1e-5);
    CHECK(std::isnan(r.registers.result("diagonal_rod_mm")));  // a router has no rods
    // grbl reads plain lines: nothing numbered, checksummed or opened by M110 went to it (the
    // twin answers those as grbl does, error:1 and error:20, and the cycle would have failed).
    const auto sent = r.rig.transcript();
    CHECK(sent.size() > 100);
    for (const auto& line : sent)
        CHECK_TEXT(line.find('*') == std::string::npos && line.find("M110") == std::string::npos,
                   line.c_str());
}

// Under a coarse, noisy camera the box measures the grid through its table at 0.012 mm mean:
// it cannot confirm the galvo goal (0.008), and says so.
TEST(AppliancePlc, a_galvo_missing_its_goal_reads_fail) {
    PlcRig r("tests/scenarios/galvo_coarse.toml");
    const auto& report = r.rig.cycle.report();
    UT_PRINT(("galvo verified " + std::to_string(*report.verified->mean_mm) + " mm mean, " +
              std::to_string(report.verified->max_mm) + " worst")
                 .c_str());
    CHECK(report.applied);
    CHECK(*report.verified->mean_mm > 0.008);
    CHECK_FALSE(r.registers.inputs[firmware::plc::kPassInput]);
    CHECK_FALSE(r.rig.cycle.goal_met());
    STRCMP_CONTAINS("goal (mean <= 0.0080 mm, worst <= 0.0300 mm): not met",
                    [&r] {
                        firmware::BoxConfig config;
                        firmware::LogBook log_book;
                        firmware::Console console({r.rig.cycle,
                                                   config,
                                                   r.rig.data,
                                                   "calbox.toml",
                                                   r.rig.data,
                                                   log_book,
                                                   "test",
                                                   {},
                                                   {}});
                        return console.reply_to("last");
                    }()
                        .c_str());
}

// The live view shares the camera with the cycle: a preview while the cycle's own capture runs is
// refused, and a capture the cycle asks for while a preview runs waits for it, so that every
// photo the cycle measures is its own; each frame reaches on_frame.
TEST(ApplianceLink, the_live_views_frames_never_take_the_cycles_place) {
    Rig rig(fresh_dir("preview"), kScenario.string(), {});
    std::vector<std::uint64_t> frames;
    const auto listening = rig.cycle.subscribe(
        {{}, {}, {}, {}, [&](const hal::Frame& f) { frames.push_back(f.metadata.sequence); }});
    CHECK_TRUE(rig.cycle.preview());
    CHECK_FALSE(rig.cycle.preview());  // one at a time
    rig.run_until([&] { return frames.size() == 1; });
    // A preview asked for, then the set-up's first view pressed at once: its capture waits.
    bool pressed = false;
    rig.intercept = [&](firmware::Prompt p) {
        if (p != firmware::Prompt::hold_calibration_board || pressed) return false;
        pressed = true;
        CHECK_TRUE(rig.cycle.preview());
        firmware::act_on_prompt(*rig.board.bench, *rig.board.lines, p, 0);
        return true;
    };
    CHECK_EQUAL(std::string(), rig.cycle.calibrate_camera());
    rig.run_until([&] {
        return std::any_of(rig.log.begin(), rig.log.end(), [](const std::string& l) {
            return l.find("view 1/") != std::string::npos && l.find("corners") != std::string::npos;
        });
    });
    // The preview's frame, then the cycle's: two more, and the view measured the cycle's.
    CHECK_EQUAL(3u, frames.size());
    const auto view = std::find_if(rig.log.begin(), rig.log.end(), [](const std::string& l) {
        return l.find("view 1/") != std::string::npos && l.find("corners") != std::string::npos;
    });
    STRCMP_CONTAINS("88 corners", view->c_str());
    rig.intercept = nullptr;
    rig.cycle.cancel("test over");
}

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
