#pragma once
// The calibration cycle as an explicit state machine, driven by the event loop:
//   idle -> [set-up: camera, plane] -> make-target -> wait-machine -> capture -> measure -> solve
//   -> review -> apply -> verify -> idle, with error reachable from every state and cancel (a
// long press, or the console) from every waiting one. It never blocks: the machine link, the
// camera and the worker report back through the loop.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/goal.hpp"
#include "firmware/cycle/button_press.hpp"
#include "firmware/cycle/cycle_mode.hpp"
#include "firmware/cycle/metering.hpp"
#include "firmware/cycle/screens.hpp"
#include "firmware/links/machine_link.hpp"
#include "firmware/loop/event_loop.hpp"
#include "firmware/settings/settings_table.hpp"
#include "hal/camera.hpp"
#include "hal/clock.hpp"
#include "hal/display.hpp"
#include "hal/lines.hpp"
#include "hal/log.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

// What the box waits for a person to do before the button press that continues.
enum class Prompt {
    none,
    start,                   // idle: press to calibrate
    hold_calibration_board,  // set-up: one view of the board per press
    lay_plane_board,         // set-up: the board flat on the bed
    clear_bed,               // before a print: the bed empty
    review,                  // short press applies, long press cancels
    acknowledge_error        // press to return to idle
};
const char* prompt_text(Prompt prompt);

// The fixed reference marks' view, taken with the plane (set-up), compared at each cycle's start.
constexpr const char* kReferenceFile = "reference.yaml";
constexpr const char* kNoReferenceMarks = "none";
// Two marks apart show a turn of the camera that one mark's small square barely does, and one
// may be knocked off or covered.
constexpr int kMinimumReferenceMarks = 2;

// Each cycle's record in the data directory (cycle-NNNN-*): what it measured, solved, sent and
// showed; the oldest are pruned past these.
struct RecordSettings {
    int keep_cycles = 50;
    std::uintmax_t max_bytes = 500'000'000;
    bool keep_photos = false;  // each capture's photos as PNG (12 MP: about 8 MB each)
};

struct CycleSettings {
    RecordSettings records;
    int frames_per_capture = 1;                  // averaged by measure
    std::chrono::milliseconds long_press{1500};  // at least this long: cancel
    int calibration_views = 12;
    std::string calibration_pattern = "chessboard:11x8@20";
    std::string plane_pattern = "chessboard:9x6@20";
    double plane_board_thickness_mm = 0;
    // The fixed reference marks' dictionary ("none": a box without them, no camera check) and
    // how far they may seem to move on the bed before a cycle stops.
    std::string reference_marks = "DICT_APRILTAG_36h11";
    double camera_moved_limit_mm = 0.05;
};

// The cycle's tables of the configuration: [cycle], [setup] and [records].
std::span<const SettingsTable<CycleSettings>> cycle_settings_tables();

struct CycleDevices {
    hal::Camera& camera;
    hal::Lines& lines;
    MachineLink& machine;
    hal::Display& display;
    hal::Clock& clock;
    hal::Storage& data;  // set-up (camera.yaml, plane.yaml) and the cycles' records
    Worker& worker;
};

// What one cycle found and did, for the log, the display and the caller; the mode's own
// (a delta's passes, a galvo's table) are the mode's (Cycle::mode()).
struct CycleReport {
    int number = 0;
    bool applied = false;
    // The target measured before the correction (a delta's placement errors; a galvo's marks
    // against its grid), and made again after it (a galvo's through the table).
    std::optional<modes::ErrorFigures> measured, verified;
    // The machine's error as jobs met it before this cycle: `measured` through the correction
    // the box keeps, if one is in force (galvo, planar), else `measured` itself. What drift and
    // "needs calibrating" ask, as the last correction's `verified` is the same error then.
    std::optional<modes::ErrorFigures> in_force;
    // The reference marks' largest apparent move on the bed since the plane was taken.
    std::optional<double> camera_move_mm;
    double box_seconds = 0;      // the box's own work: measuring, solving, set-up solves
    double camera_seconds = 0;   // waiting for the camera (the twin's rendering on the sim board)
    double machine_seconds = 0;  // waiting for the machine
};

// What a listener hears of the cycle; each part may be left empty.
struct CycleNews {
    std::function<void(Prompt, int step)> prompt;   // every prompt (the operator acts on them)
    std::function<void(CycleState)> state;          // every state change
    std::function<void(bool completed)> cycle_end;  // a cycle ended, done or not
    // What a person at the console should read now: each set-up view's result, the set-up's.
    std::function<void(const std::string&)> notice;
    // Each frame the camera gives: a preview's, and the first of each of the cycle's captures.
    std::function<void(const hal::Frame&)> frame;
};

// One listener's subscription: it ends when destroyed (move it where the listener lives).
class CycleSubscription {
  public:
    CycleSubscription() = default;
    CycleSubscription(std::shared_ptr<std::list<CycleNews>> listeners,
                      std::list<CycleNews>::iterator at)
        : listeners_(std::move(listeners)), at_(at) {}
    CycleSubscription(CycleSubscription&& other) noexcept { *this = std::move(other); }
    CycleSubscription& operator=(CycleSubscription&& other) noexcept {
        if (this != &other) {
            end();
            listeners_ = std::exchange(other.listeners_, nullptr);
            at_ = other.at_;
        }
        return *this;
    }
    CycleSubscription(const CycleSubscription&) = delete;
    CycleSubscription& operator=(const CycleSubscription&) = delete;
    ~CycleSubscription() { end(); }
    void end() {
        if (const auto listeners = std::exchange(listeners_, nullptr)) listeners->erase(at_);
    }

  private:
    std::shared_ptr<std::list<CycleNews>> listeners_;
    std::list<CycleNews>::iterator at_;
};

class Cycle final : private CycleSteps {
  public:
    using Log = hal::Log;
    Cycle(CycleDevices devices, const models::MachineFile& machine, CycleSettings settings,
          Log log);
    Cycle(const Cycle&) = delete;
    Cycle& operator=(const Cycle&) = delete;
    ~Cycle();

    // Wire these to the event loop: readable button line, camera completion, blink timer.
    void on_button();
    void on_camera();
    void on_blink();
    int blink_fd() const { return blink_->fd(); }

    // The console's verbs: start is a short press in idle, cancel a long press in a waiting
    // state (or any busy one), acknowledge a press in error.
    void start();
    void cancel(const std::string& why);
    void acknowledge();
    void press(bool long_press);  // a whole press, as the button gives it
    // Sends the settings backed up before the last completed cycle applied its correction, then
    // reads them back (apply, then idle; error on a mismatch). Only from idle: returns why not,
    // empty when it started.
    std::string revert();
    // The set-up on its own, from idle (the console's `camera calibrate` and `camera plane`):
    // the camera's views then the plane, or the plane alone; back to idle after it. Returns why
    // not, empty when it started.
    std::string calibrate_camera();
    std::string take_plane();
    double setup_coverage() const { return setup_coverage_; }
    // The set-up's board views so far (their corners: the live view's coverage).
    const std::vector<geometry::ObservedView>& setup_views() const { return calibration_views_; }
    // One frame for the live view, handed to on_frame. Only while the cycle's own capture is not
    // under way (false then); a capture the cycle starts meanwhile waits for it, so the cycle's
    // photos are never the live view's. Nor while the box computes (measures, solves): a frame
    // then would take memory and a core from the computation at its peak, on a board with few of
    // either; the page shows the photo being measured meanwhile.
    bool preview();
    // A screen another part shows when asked (the network's), until the cycle's next.
    void show_aside(const hal::MonoBitmap& frame) { show(frame); }
    // New settings (the console changed the configuration): in force at once in idle, else
    // from the next cycle, so that a running one keeps what it started with.
    void set_settings(CycleSettings settings);
    const CycleSettings& settings() const { return settings_; }

    CycleState state() const { return state_; }
    Prompt prompt() const { return prompt_; }
    int prompt_step() const { return prompt_step_; }  // which board view, from 0
    const std::string& error() const { return error_; }
    CycleState failed_in() const { return failed_in_; }  // the stage the last error stopped
    const CycleReport& report() const { return report_; }
    int cycles_completed() const { return completed_; }
    // The machine's mode: its goal, its own figures of the last cycle, the correction it keeps.
    const CycleMode& mode() const { return *mode_; }
    const models::MachineFile& machine() const { return mode_->machine(); }
    // The last cycle completed and its own verification met the mode's goal.
    bool goal_met() const;

    // What the cycle tells its listeners (the PLC, the network's windows, the console, the sim
    // board's operator), each subscribing itself; told in the order they subscribed. The
    // subscription ends with its token.
    [[nodiscard]] CycleSubscription subscribe(CycleNews news);

  private:
    // CycleSteps: what the mode's steps ask of the cycle.
    void work(std::function<void()> job, std::function<void()> then) override;
    void run_job(const std::vector<std::string>& lines,
                 std::function<void(const JobOutcome&)> then) override;
    void ask_machine(std::function<void(MachineLink&, MachineLink::Done)> start,
                     std::function<void(const JobOutcome&)> then, bool failure_is_error) override;
    const MachineLink& machine_link() const override { return d_.machine; }
    bool keep(const std::string& name, const std::string& contents) override;
    std::optional<std::string> read(const std::string& name) const override;
    std::string record_name(const std::string& what) const override;
    void enter(CycleState next, const std::string& detail) override;
    void log(const std::string& line, hal::LogLevel level = hal::LogLevel::info) override;
    void log_detail(const std::string& line) override { log_(line); }
    void notice(const std::string& what) override;
    void fail(const std::string& message) override { fail(message, {}); }

    void ask(Prompt prompt, int step, std::function<void()> then);
    // `hint`: the error screen's line when the stage's usual one would mislead.
    void fail(const std::string& message, const std::string& hint);
    void show(const hal::MonoBitmap& frame);
    void close_record();
    void prune_records();
    ProgressScreen progress_screen(const std::string& detail) const;
    IdleScreen idle_screen() const;
    void set_leds();
    void indicate(bool& failed, const char* what, const std::function<void()>& update);
    // Asynchronous steps: each continues only if the cycle was not cancelled meanwhile.
    void capture(int frames, std::function<void(std::vector<hal::Frame>)> then);
    // The camera takes `request`; `then` gets its frames (the light on meanwhile).
    void shoot(const hal::CaptureRequest& request,
               std::function<void(std::vector<hal::Frame>)> then);
    // A capture of the work with the box's own exposure (metering.hpp): `what` names it in the
    // record (cycle-NNNN-exposure.json keeps every capture's).
    void capture_metered(const std::string& what, int frames,
                         std::function<void(std::vector<hal::Frame>)> then);
    struct MeteredRun;
    void metered_reading(const std::shared_ptr<MeteredRun>& run, std::vector<hal::Frame> f);
    void metered_capture(const std::shared_ptr<MeteredRun>& run);
    bool current(unsigned generation) const { return generation == generation_; }

    void begin_cycle();
    void setup_camera_view(int view);
    void take_calibration_view(int view, const hal::Frame& frame,
                               const std::optional<geometry::BoardObservation>& found);
    void take_next_settings();
    void setup_plane();
    // The plane's photo measured: its files kept, then the set-up ends or the cycle goes on.
    void keep_plane(const std::string& yaml, const std::string& reference_yaml,
                    const std::string& summary);
    // The camera's view of the reference marks against the one stored with the plane: a cycle
    // goes on only if they have not moved.
    void check_camera();
    void ask_clear_bed_then_target();
    void make_target();
    // Photographs what was made and has the mode measure it.
    void measure_print(CycleState state, std::function<void()> then);
    void solve();
    void review();
    void apply();
    void verify();
    void finish_cycle();

    CycleDevices d_;
    CycleSettings settings_;
    std::optional<CycleSettings> next_settings_;
    Log log_;
    std::unique_ptr<CycleMode> mode_;
    std::unique_ptr<hal::Timer> blink_;
    bool blink_phase_ = false;

    CycleState state_ = CycleState::idle;
    Prompt prompt_ = Prompt::start;
    int prompt_step_ = 0;
    std::function<void()> after_press_;
    CycleState failed_in_ = CycleState::idle;
    bool display_failed_ = false, leds_failed_ = false;  // told once, until they work again
    PressClassifier presses_{settings_.long_press};
    unsigned generation_ = 0;  // bumped by cancel and error: late completions are dropped
    std::string error_;
    int completed_ = 0;

    // The cycle's working data.
    std::vector<geometry::ObservedView> calibration_views_;
    std::array<int, 2> image_size_{0, 0};
    double setup_coverage_ = 0;  // of the image, by the views taken so far
    bool setup_only_ = false;    // the set-up asked for on its own: back to idle after it
    std::function<void(std::vector<hal::Frame>)> pending_capture_;
    std::vector<CaptureExposure> exposures_;  // this cycle's metered captures, for its record
    hal::CaptureRequest metering_start_;      // the last metered capture's exposure
    // Told in subscription order. A listener may end any subscription while being told: each
    // is looked up again before it is told, so none ended meanwhile is.
    template <class Part, class... Args>
    void tell(Part CycleNews::*part, const Args&... args) {
        const auto listeners = listeners_;
        std::vector<const CycleNews*> round;
        for (const auto& news : *listeners) round.push_back(&news);
        for (const CycleNews* news : round) {
            const bool still_there = std::any_of(listeners->begin(), listeners->end(),
                                                 [news](const CycleNews& n) { return &n == news; });
            if (still_there && news->*part) (news->*part)(args...);
        }
    }
    std::shared_ptr<std::list<CycleNews>> listeners_ = std::make_shared<std::list<CycleNews>>();
    bool previewing_ = false;  // the camera is taking a preview
    // The capture the cycle waits to start until the preview is done.
    std::optional<hal::CaptureRequest> capture_after_preview_;
    std::vector<std::string> target_job_;
    CycleReport report_;
    std::chrono::nanoseconds phase_started_{0};
    std::chrono::nanoseconds cycle_started_{0};
    // Seconds per state (CycleState's order) in this cycle and the last completed one: the
    // progress screen's time left.
    std::array<double, 12> stage_seconds_{};
    std::optional<std::array<double, 12>> last_stage_seconds_;
    std::chrono::nanoseconds entered_at_{0};
    bool cycle_running_ = false;                  // a cycle's record is open
    std::vector<hal::MonoBitmap> cycle_screens_;  // what the display showed during it
};

// Wires a cycle and its devices to the loop: the machine link, the button, the camera's
// completion and the blink timer. `calbox run` and the tests wire it the same way.
void watch_cycle(EventLoop& loop, Cycle& cycle, MachineLink& machine, hal::Camera& camera,
                 hal::Lines& lines);

}  // namespace calbox::firmware
