#pragma once
// The cycle's view of a calibration mode (DESIGN.md, "A calibration mode"): its target job,
// whether the machine's settings are read (and probed) first, measure (with its overlay), solve
// (with its record files), the review, apply, the verification job and its verdict, revert, and
// its goal. The cycle (firmware/cycle/cycle.hpp) runs the same states for every mode and asks the
// mode at each; make_cycle_mode is the one place on the box's side that reads the machine's kind.
// The pure half of each mode is core/modes/<mode>; the adapters in firmware/modes are thin.
#include <functional>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/jobs/compensate.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/goal.hpp"
#include "firmware/cycle/screens.hpp"
#include "firmware/links/job_text.hpp"
#include "firmware/links/machine_link.hpp"
#include "hal/camera.hpp"
#include "hal/log.hpp"

namespace calbox::firmware {

enum class CycleState {
    idle,
    setup_camera,
    setup_plane,
    make_target,
    wait_machine,
    capture,
    measure,
    solve,
    review,
    apply,
    verify,
    error
};
const char* state_name(CycleState state);

// What a mode's steps ask of the cycle. Each asynchronous one continues only while the cycle that
// started it runs: a cancel or an error drops late completions, so a mode never sees them.
class CycleSteps {
  public:
    virtual ~CycleSteps() = default;
    // `job` runs off the loop and touches only what it captured; `then` runs on the loop.
    virtual void work(std::function<void()> job, std::function<void()> then) = 0;
    // A job the machine runs; a failed one puts the cycle in error and `then` is not called.
    virtual void run_job(const std::vector<std::string>& lines,
                         std::function<void(const JobOutcome&)> then) = 0;
    // Any request to the machine link: `start` makes it, handing the link the completion. A
    // failed one puts the cycle in error unless `failure_is_error` is false: `then` gets it.
    virtual void ask_machine(std::function<void(MachineLink&, MachineLink::Done)> start,
                             std::function<void(const JobOutcome&)> then,
                             bool failure_is_error) = 0;
    // Commands whose replies the mode reads (a settings report, a probe), as ask_machine.
    void send_commands(const std::vector<std::string>& lines,
                       std::function<void(const JobOutcome&)> then) {
        ask_machine([lines](MachineLink& m,
                            MachineLink::Done done) { m.send_commands(lines, std::move(done)); },
                    std::move(then), true);
    }
    virtual const MachineLink& machine_link() const = 0;
    // Klipper through a host that keeps its printer.cfg (MachineLink::has_config_file): the
    // correction goes into that file, and the settings Klipper took are read back from the host.
    bool klipper_on_host(const models::MachineFile& machine) const {
        return machine.firmware == "klipper" && machine_link().has_config_file();
    }
    // The settings the printer has in force, as `parse` reads them; a text `parse` refuses (it
    // throws) puts the cycle in error with its message, and `then` is not called.
    template <typename Settings>
    void read_settings_in_force(std::function<Settings(const std::string&)> parse,
                                std::function<void(Settings)> then) {
        ask_machine(
            [](MachineLink& m, MachineLink::Done done) {
                m.read_settings_in_force(std::move(done));
            },
            [this, parse = std::move(parse), then = std::move(then)](const JobOutcome& outcome) {
                std::optional<Settings> settings;
                try {
                    settings = parse(outcome.text);
                } catch (const std::exception& e) {
                    fail(e.what());
                    return;
                }
                then(std::move(*settings));
            },
            true);
    }
    // A file in the data directory; false (and the cycle in error) when it could not be kept.
    virtual bool keep(const std::string& name, const std::string& contents) = 0;
    virtual std::optional<std::string> read(const std::string& name) const = 0;
    // This cycle's record: "cycle-NNNN-" + what.
    virtual std::string record_name(const std::string& what) const = 0;
    virtual void enter(CycleState state, const std::string& detail) = 0;
    // "cycle N: " + line, at how much it matters (hal/log.hpp)
    virtual void log(const std::string& line, hal::LogLevel level = hal::LogLevel::info) = 0;
    virtual void log_detail(const std::string& line) = 0;  // as it is: "  M665 ..."
    virtual void notice(const std::string& line) = 0;      // the log, and the console's notice
    virtual void fail(const std::string& message) = 0;
};

// The photos a capture gave, the set-up they are measured with, and where the overlay of what
// was found goes in the cycle's record.
struct MeasureInput {
    std::shared_ptr<const std::vector<hal::Frame>> frames;
    std::string camera_yaml, plane_yaml;
    std::string overlay_name;
};

struct SolveOutcome {
    enum class Next {
        review,  // the owner confirms the correction (a press, the console, the PLC)
        apply,   // the same calibration carried on: a later pass of one confirmed at its first
        done     // the machine holds: nothing to send
    };
    Next next = Next::review;
    modes::ErrorFigures measured;  // the target as made before this correction
    // The machine's error as jobs meet it now: `measured` where the correction lives in the
    // machine (a delta's, as printed), `measured` through the correction the box keeps and sends
    // jobs through where one is in force (galvo, planar: the target is made without it).
    modes::ErrorFigures in_force;
};

struct ReviewText {
    std::string detail;    // the review state's line
    std::string proposed;  // the log's line: what would change, and what it should leave
    std::vector<std::string> details;  // logged as they are: the commands to be sent
    ReviewScreen screen;
};

struct VerifyOutcome {
    modes::ErrorFigures verified;
    bool solve_again = false;  // the verification print is the next pass's measurement
};

// What a completed cycle hands a controller over Modbus: named values (the names of
// result_value_names(); a mode leaves out what it does not have) and, for a mode whose correction
// is a table, the table's floats (docs/devices.md, "The table over Modbus").
struct ModeResult {
    std::vector<std::pair<std::string, double>> values;
    std::vector<float> table;
    std::string table_key;  // the ModeTable (mode_tables()) it is written as
};

// A correction a mode keeps as a table that a controller can read from its holding registers:
// where it goes unless the map file's `key = N` moves it, and how many registers it takes.
struct ModeTable {
    std::string key;   // the map file's key: "galvo_table"
    std::string what;  // in messages: "the galvo table"
    int registers = 0;
    int default_register = 0;
};

class CycleMode {
  public:
    virtual ~CycleMode() = default;
    virtual const models::MachineFile& machine() const = 0;
    virtual modes::ModeGoal goal() const = 0;
    // A new cycle (or a revert): the last one's working data cleared.
    virtual void begin() = 0;

    // 1. Target: the job, worked out off the loop.
    virtual void make_target(std::function<void(std::vector<std::string>)> then) = 0;
    // With the bed clear, before the target is made: a printer's settings in force read, its
    // probe. Most modes go straight on.
    virtual void before_target(std::function<void()> then) = 0;
    // 2. Measure the photos of the target (or of the verification job) into the mode's working
    // data; its overlay is kept in the record (input.overlay_name) before `then`.
    virtual void measure(MeasureInput input, std::function<void()> then) = 0;
    // 3. Solve what was measured last, keeping its record files.
    virtual void solve(std::function<void(SolveOutcome)> then) = 0;
    virtual ReviewText review() const = 0;
    // 4. Apply the solved correction: `then(true)` goes on to the verification, `then(false)`
    // ends the cycle there (a correction the box cannot send).
    virtual void apply(std::function<void(bool verify)> then) = 0;
    virtual std::string verify_detail() const = 0;
    // The target made again on the corrected machine: through the correction when the box keeps
    // one.
    virtual void verification_job(const std::vector<std::string>& target,
                                  std::function<void(std::vector<std::string>)> then) = 0;
    // What the verification measured, judged (its record files kept).
    virtual void judge_verification(std::function<void(VerifyOutcome)> then) = 0;
    // A later pass's record files carry this before their names ("pass-2-"); "" for the first.
    virtual std::string pass_prefix() const { return {}; }

    // Puts back what was in force before cycle `number` applied its correction. Returns why
    // not (nothing started), or "" and `then(what)` once it is back.
    virtual std::string revert(int number, std::function<void(std::string what)> then) = 0;
    // The correction the box sends jobs through, as kept in its data directory (none for a
    // machine whose own settings were corrected).
    virtual std::optional<jobs::KeptCorrection> kept_correction() const { return std::nullopt; }
    // The result file of that correction, as kept (for jobs compensated through the box).
    virtual std::optional<std::string> kept_result_text() const { return std::nullopt; }
    // The files the mode keeps in the data directory beside the cycles' records (its
    // correction in force), by name: the web page serves them with the records.
    virtual std::vector<std::string> kept_files() const { return {}; }

    // The last cycle's own figures: for the console's `last` (text lines and JSON keys) and a
    // controller.
    virtual void describe_last(std::string& text, nlohmann::json& data) const = 0;
    virtual ModeResult result(bool applied) const = 0;
};

// `compute` off the loop (touching only what it captured), then `then` with its value on the loop.
template <class T>
void work_out(CycleSteps& steps, std::function<T()> compute, std::function<void(T)> then) {
    auto value = std::make_shared<T>();
    steps.work([compute = std::move(compute), value] { *value = compute(); },
               [value, then = std::move(then)] { then(std::move(*value)); });
}

// The one place the box's side reads the machine's kind.
std::unique_ptr<CycleMode> make_cycle_mode(const models::MachineFile& machine, CycleSteps& steps);
// The values the modes' results may carry (ModeResult::values), each mode's as it declares
// them, in turn: the PLC's result block holds them in this order after the cycle's own.
std::vector<std::string> mode_result_names();
// The tables the modes' results may carry (ModeResult::table), each mode's as it declares it.
std::vector<ModeTable> mode_tables();

}  // namespace calbox::firmware
