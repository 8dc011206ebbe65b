#pragma once
// The appliance's test rig (test_appliance*.cpp): the sim board's box, its twin printer behind a
// pty and the rendering camera, on simulated time; a process's set-up prepared once.
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

namespace appliance_rig {

// A delta printer's cycle: its passes and the correction sent.
inline const firmware::DeltaCycleMode& delta_of(const firmware::Cycle& cycle) {
    return dynamic_cast<const firmware::DeltaCycleMode&>(cycle.mode());
}

inline const fs::path kScenario =
    fs::path(CALBOX_SOURCE_DIR) / "tests/scenarios/delta_cycle_small.toml";

// A fresh directory in the temporary area, one set per process (ctest runs the groups side by
// side and each builds its own set-up), all removed when the process ends.
inline fs::path fresh_dir(const std::string& name) {
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
inline std::string scenario_with(const std::string& name, const std::string& extra) {
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
inline const fs::path& prepared_setup() {
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

inline fs::path prepared_dir(const std::string& name) {
    const fs::path d = fresh_dir(name);
    for (const char* f : {"camera.yaml", "plane.yaml", firmware::kReferenceFile})
        fs::copy_file(prepared_setup() / f, d / f);
    return d;
}

// XOR of the bytes before '*', worked here rather than by the code under test.
inline bool checksum_holds(const std::string& line) {
    const auto star = line.find('*');
    if (star == std::string::npos) return false;
    unsigned sum = 0;
    for (std::size_t i = 0; i < star; ++i) sum ^= static_cast<unsigned char>(line[i]);
    return std::to_string(sum) == line.substr(star + 1);
}

// The command of "N12 G1 X1*34": "G1 X1".
inline std::string command_of(const std::string& line) {
    const auto space = line.find(' ');
    return line.substr(space + 1, line.find('*') - space - 1);
}

// The transcript as jobs, each opened by N0 M110 N0, its lines numbered on from 1, every
// checksum right: each job's commands.
inline std::vector<std::vector<std::string>> jobs_of(const std::vector<std::string>& transcript) {
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

inline void check_error_state(Rig& rig, const char* message_part) {
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

}  // namespace appliance_rig

using namespace appliance_rig;
