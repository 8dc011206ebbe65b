#include "firmware/cycle/cycle.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include "core/geometry/calibration.hpp"
#include "core/number_text.hpp"
#include "core/vision/reference_marks.hpp"
#include "firmware/cycle/metering.hpp"
#include "firmware/cycle/png.hpp"
#include "firmware/cycle/screens.hpp"

namespace calbox::firmware {
namespace {

double seconds(std::chrono::nanoseconds d) {
    return std::chrono::duration<double>(d).count();
}

std::string record_file_name(int cycle, const std::string& what) {
    char b[32];
    std::snprintf(b, sizeof b, "cycle-%04d-", cycle);
    return b + what;
}

// The error screen's one line: what to look at first when a stage fails.
std::string hint_for(CycleState stage) {
    switch (stage) {
        case CycleState::setup_camera:
            return "whole board in view?";
        case CycleState::setup_plane:
            return "board flat, in view?";
        case CycleState::make_target:
        case CycleState::wait_machine:
            return "check machine + link";
        case CycleState::capture:
            return "check camera + light";
        case CycleState::measure:
            return "target in view, lit?";
        case CycleState::solve:
            return "fit refused: see log";
        case CycleState::apply:
            return "machine: see the log";
        case CycleState::verify:
            return "check machine+camera";
        default:
            return "see the log";
    }
}

}  // namespace

const char* state_name(CycleState s) {
    switch (s) {
        case CycleState::idle:
            return "idle";
        case CycleState::setup_camera:
            return "setup-camera";
        case CycleState::setup_plane:
            return "setup-plane";
        case CycleState::make_target:
            return "make-target";
        case CycleState::wait_machine:
            return "wait-machine";
        case CycleState::capture:
            return "light+capture";
        case CycleState::measure:
            return "measure";
        case CycleState::solve:
            return "solve";
        case CycleState::review:
            return "review";
        case CycleState::apply:
            return "apply";
        case CycleState::verify:
            return "verify";
        case CycleState::error:
            return "error";
    }
    return "?";
}

const char* prompt_text(Prompt p) {
    switch (p) {
        case Prompt::none:
            return "";
        case Prompt::start:
            return "press to calibrate";
        case Prompt::hold_calibration_board:
            return "hold the board in view, press";
        case Prompt::lay_plane_board:
            return "lay the board on the bed, press";
        case Prompt::clear_bed:
            return "clear the bed, press";
        case Prompt::review:
            return "press: apply, hold: cancel";
        case Prompt::acknowledge_error:
            return "press to acknowledge";
    }
    return "";
}

Cycle::Cycle(CycleDevices devices, const models::MachineFile& machine, CycleSettings settings,
             Log log)
    : d_(devices),
      settings_(std::move(settings)),
      log_(std::move(log)),
      mode_(make_cycle_mode(machine, *this)),
      blink_(d_.clock.make_timer()) {
    blink_->arm(std::chrono::milliseconds(500), std::chrono::milliseconds(500));
    set_leds();
    show(draw_screen(idle_screen()));
}

Cycle::~Cycle() = default;

void Cycle::enter(CycleState next, const std::string& detail) {
    log_(std::string("cycle ") + std::to_string(report_.number) + ": " + state_name(state_) +
         " -> " + state_name(next) + (detail.empty() ? "" : " (" + detail + ")"));
    const auto now = d_.clock.now();
    stage_seconds_[static_cast<std::size_t>(state_)] += seconds(now - entered_at_);
    entered_at_ = now;
    state_ = next;
    prompt_ = next == CycleState::idle ? Prompt::start : Prompt::none;
    after_press_ = nullptr;
    set_leds();
    if (next == CycleState::idle)
        show(draw_screen(idle_screen()));
    else
        show(draw_screen(progress_screen(detail)));
    tell(&CycleNews::state, next);
}

// LEDs per state: ready steady in idle, busy blinking while working, busy steady while waiting
// for a person, error steady in error.
// The LEDs and the display only show what the log also says: a failing one (a noisy I2C bus, a
// GPIO line gone) is told once and the cycle goes on, rather than stopping a machine mid-job.
void Cycle::indicate(bool& failed, const char* what, const std::function<void()>& update) {
    try {
        update();
        failed = false;
    } catch (const std::runtime_error& e) {
        if (!failed)
            log_.warning(std::string(what) + ": " + e.what() + " (the box goes on without it)");
        failed = true;
    }
}

void Cycle::set_leds() {
    const bool idle = state_ == CycleState::idle;
    const bool error = state_ == CycleState::error;
    const bool waiting = prompt_ != Prompt::none && !idle && !error;
    indicate(leds_failed_, "status LEDs", [&] {
        d_.lines.set_led(hal::Led::ready, idle || waiting);
        d_.lines.set_led(hal::Led::busy, !idle && !error && (waiting || blink_phase_));
        d_.lines.set_led(hal::Led::error, error);
    });
}

void Cycle::on_blink() {
    if (blink_->take_expirations() == 0) return;
    blink_phase_ = !blink_phase_;
    set_leds();
}

void Cycle::show(const hal::MonoBitmap& frame) {
    indicate(display_failed_, "display", [&] { d_.display.show(frame); });
    if (cycle_running_) cycle_screens_.push_back(frame);
}

bool Cycle::keep(const std::string& name, const std::string& contents) {
    try {
        d_.data.replace_file(name, contents);
        return true;
    } catch (const std::runtime_error& e) {
        // A full disk or a failing card: nothing half-written (the save is atomic) and, as
        // every record is kept before the step that needs it, nothing sent on the strength of it.
        fail(std::string("records: ") + e.what());
        return false;
    }
}

// The end of a cycle, whatever its outcome: its display frames join its record, and the oldest
// records go past the configured count and size. A failure here is told, never fatal: the
// cycle's own outcome is already decided.
void Cycle::close_record() {
    if (!cycle_running_) return;
    cycle_running_ = false;
    try {
        for (std::size_t i = 0; i < cycle_screens_.size(); ++i) {
            char what[32];
            std::snprintf(what, sizeof what, "screen-%02zu.png", i + 1);
            d_.data.replace_file(record_file_name(report_.number, what), png_of(cycle_screens_[i]));
        }
        prune_records();
    } catch (const std::runtime_error& e) {
        log(std::string("records: ") + e.what(), hal::LogLevel::error);
    }
    cycle_screens_.clear();
}

void Cycle::prune_records() {
    std::map<int, std::vector<hal::Storage::Entry>> records;  // by cycle number
    for (auto& entry : d_.data.list_files()) {
        int number = 0;
        if (std::sscanf(entry.name.c_str(), "cycle-%4d-", &number) == 1 && number > 0 &&
            entry.name.size() > 11 && entry.name[10] == '-')
            records[number].push_back(std::move(entry));
    }
    std::uintmax_t total = 0;
    for (const auto& [number, files] : records)
        for (const auto& f : files) total += f.size_bytes;
    int left = static_cast<int>(records.size());
    for (const auto& [number, files] : records) {
        const bool too_many = left > settings_.records.keep_cycles;
        const bool too_big = total > settings_.records.max_bytes;
        if ((!too_many && !too_big) || number >= report_.number) break;  // never the newest
        for (const auto& f : files) {
            d_.data.remove_file(f.name);
            total -= f.size_bytes;
        }
        --left;
        log_("records: cycle " + std::to_string(number) + "'s record pruned");
    }
}

// The stages a cycle goes through, in order, for the progress bar.
constexpr CycleState kCycleStages[] = {
    CycleState::make_target, CycleState::wait_machine, CycleState::capture, CycleState::measure,
    CycleState::solve,       CycleState::review,       CycleState::apply,   CycleState::verify};

ProgressScreen Cycle::progress_screen(const std::string& detail) const {
    ProgressScreen p;
    p.stage = state_name(state_);
    p.detail = detail;
    const auto* at = std::find(std::begin(kCycleStages), std::end(kCycleStages), state_);
    const auto index = static_cast<double>(at - std::begin(kCycleStages));
    p.fraction = at == std::end(kCycleStages) ? 0 : index / std::size(kCycleStages);
    // The time left: what the stages from here took in the last completed cycle. A person's
    // time (review) is theirs, not the box's, and is left out.
    if (last_stage_seconds_ && at != std::end(kCycleStages)) {
        double left = 0;
        for (const auto* s = at; s != std::end(kCycleStages); ++s)
            if (*s != CycleState::review)
                left += (*last_stage_seconds_)[static_cast<std::size_t>(*s)];
        p.seconds_left = static_cast<int>(std::lround(left));
    }
    return p;
}

IdleScreen Cycle::idle_screen() const {
    IdleScreen idle{machine().kind + " " + machine().firmware, "no cycle yet", {}};
    if (completed_ > 0 && report_.measured && report_.verified)
        idle.last_result = "last " + number_text("%.3f", report_.measured->rms_mm) + "->" +
                           number_text("%.3f", report_.verified->rms_mm) + " mm";
    if (completed_ > 0 && report_.verified)
        idle.verdict = goal_met() ? "goal met" : "short of goal";
    return idle;
}

void Cycle::ask(Prompt prompt, int step, std::function<void()> then) {
    prompt_ = prompt;
    prompt_step_ = step;
    after_press_ = std::move(then);
    set_leds();
    std::string what = prompt_text(prompt);
    if (prompt == Prompt::hold_calibration_board)
        what = "board view " + std::to_string(step + 1) + "/" +
               std::to_string(settings_.calibration_views) + ": " + what;
    log_("cycle " + std::to_string(report_.number) + ": waiting: " + what);
    if (prompt != Prompt::review) {
        PromptScreen screen{state_name(state_), prompt_text(prompt), {}, {}};
        if (prompt == Prompt::hold_calibration_board) {
            screen.title = "set-up: camera";
            screen.step = "view " + std::to_string(step + 1) + "/" +
                          std::to_string(settings_.calibration_views);
            screen.coverage = setup_coverage_;
        } else if (prompt == Prompt::lay_plane_board) {
            screen.title = "set-up: bed plane";
        }
        show(draw_screen(screen));
    }
    tell(&CycleNews::prompt, prompt, step);
}

void Cycle::on_button() {
    while (const auto event = d_.lines.read_button()) {
        if (const auto press_made = presses_.on_event(*event)) {
            press(*press_made == Press::long_press);
        }
    }
}

void Cycle::press(bool long_press) {
    if (state_ == CycleState::idle) {
        if (!long_press) start();
        return;
    }
    if (state_ == CycleState::error) {
        acknowledge();
        return;
    }
    if (long_press) {
        cancel("cancelled by a long press");
        return;
    }
    if (prompt_ != Prompt::none && after_press_) {
        auto then = std::move(after_press_);
        after_press_ = nullptr;
        prompt_ = Prompt::none;
        set_leds();
        then();
    }
}

void Cycle::start() {
    if (state_ != CycleState::idle) return;
    begin_cycle();
}

void Cycle::cancel(const std::string& why) {
    if (state_ == CycleState::idle || state_ == CycleState::error) return;
    ++generation_;
    d_.machine.cancel(why);
    d_.lines.set_light(false);
    log_("cycle " + std::to_string(report_.number) + ": " + why);
    enter(CycleState::idle, why);
    close_record();
    tell(&CycleNews::cycle_end, false);
}

void Cycle::acknowledge() {
    if (state_ != CycleState::error) return;
    enter(CycleState::idle, "error acknowledged");
}

void Cycle::fail(const std::string& message, const std::string& hint) {
    ++generation_;
    d_.machine.cancel(message);  // nothing more goes to the machine
    d_.lines.set_light(false);
    error_ = message;
    failed_in_ = state_;
    log("error: " + message, hal::LogLevel::error);
    state_ = CycleState::error;
    prompt_ = Prompt::acknowledge_error;
    set_leds();
    show(draw_screen(ErrorScreen{static_cast<int>(failed_in_),
                                 hint.empty() ? hint_for(failed_in_) : hint, message}));
    tell(&CycleNews::state, state_);
    close_record();
    tell(&CycleNews::cycle_end, false);
    tell(&CycleNews::prompt, prompt_, 0);
}

void Cycle::work(std::function<void()> job, std::function<void()> then) {
    if (d_.worker.busy()) {
        // A cancelled cycle's computation still runs; its result will be dropped.
        fail(std::string(state_name(state_)) + ": the previous computation is still running");
        return;
    }
    const unsigned generation = generation_;
    const auto started = d_.clock.now();
    d_.worker.start(std::move(job), [this, generation, started,
                                     then = std::move(then)](const std::exception_ptr& error) {
        if (!current(generation)) return;
        report_.box_seconds += seconds(d_.clock.now() - started);
        if (error) {
            try {
                std::rethrow_exception(error);
            } catch (const std::exception& e) {
                fail(std::string(state_name(state_)) + ": " + e.what());
            }
            return;
        }
        then();
    });
}

void Cycle::run_job(const std::vector<std::string>& lines,
                    std::function<void(const JobOutcome&)> then) {
    ask_machine(
        [&lines](MachineLink& m, MachineLink::Done done) { m.run_job(lines, std::move(done)); },
        std::move(then), true);
}

void Cycle::ask_machine(std::function<void(MachineLink&, MachineLink::Done)> start,
                        std::function<void(const JobOutcome&)> then, bool failure_is_error) {
    const unsigned generation = generation_;
    const auto started = d_.clock.now();
    start(d_.machine, [this, generation, started, failure_is_error,
                       then = std::move(then)](const JobOutcome& outcome) {
        if (!current(generation)) return;
        report_.machine_seconds += seconds(d_.clock.now() - started);
        if (!outcome.ok && failure_is_error) {
            fail("machine: " + outcome.error);
            return;
        }
        then(outcome);
    });
}

void Cycle::set_settings(CycleSettings settings) {
    next_settings_ = std::move(settings);
    if (state_ == CycleState::idle) take_next_settings();
}

void Cycle::take_next_settings() {
    if (!next_settings_) return;
    settings_ = std::move(*next_settings_);
    next_settings_.reset();
    presses_ = PressClassifier(settings_.long_press);
}

std::optional<std::string> Cycle::read(const std::string& name) const {
    return d_.data.read_file(name);
}

std::string Cycle::record_name(const std::string& what) const {
    return record_file_name(report_.number, what);
}

CycleSubscription Cycle::subscribe(CycleNews news) {
    listeners_->push_back(std::move(news));
    return {listeners_, std::prev(listeners_->end())};
}

void Cycle::log(const std::string& line, hal::LogLevel level) {
    log_.write(level, "cycle " + std::to_string(report_.number) + ": " + line);
}

void Cycle::notice(const std::string& what) {
    log(what);
    tell(&CycleNews::notice, what);
}

void Cycle::begin_cycle() {
    take_next_settings();
    stage_seconds_ = {};
    cycle_screens_.clear();
    exposures_.clear();
    report_ = CycleReport{};
    mode_->begin();
    const auto last = d_.data.read_file("last-cycle");
    report_.number = (last ? std::atoi(last->c_str()) : 0) + 1;
    cycle_running_ = true;
    cycle_started_ = d_.clock.now();
    error_.clear();
    setup_only_ = false;
    if (!d_.data.read_file("camera.yaml")) {
        calibration_views_.clear();
        setup_coverage_ = 0;
        enter(CycleState::setup_camera, "set-up: calibrating the camera from " +
                                            std::to_string(settings_.calibration_views) +
                                            " views of " + settings_.calibration_pattern);
        setup_camera_view(0);
    } else if (!d_.data.read_file("plane.yaml")) {
        enter(CycleState::setup_plane, "set-up: the bed plane");
        setup_plane();
    } else {
        check_camera();
    }
}

void Cycle::ask_clear_bed_then_target() {
    enter(CycleState::make_target, "the " + machine().kind + " target for " + machine().firmware);
    ask(Prompt::clear_bed, 0, [this] { make_target(); });
}

void Cycle::make_target() {
    mode_->make_target([this](std::vector<std::string> lines) {
        target_job_ = std::move(lines);
        mode_->before_target([this] {
            enter(CycleState::wait_machine,
                  "making the target: " + std::to_string(target_job_.size()) + " lines");
            run_job(target_job_, [this](const JobOutcome&) {
                enter(CycleState::capture,
                      std::to_string(settings_.frames_per_capture) + " frame(s)");
                measure_print(CycleState::measure, [this] { solve(); });
            });
        });
    });
}

void Cycle::measure_print(CycleState state, std::function<void()> then) {
    // A verification's files carry its pass ("pass-2-verify-overlay.png"), as its exposure does.
    const std::string what =
        state == CycleState::verify ? mode_->pass_prefix() + "verify" : "target";
    capture_metered(
        what, settings_.frames_per_capture,
        [this, state, what, then = std::move(then)](std::vector<hal::Frame> f) {
            auto frames = std::make_shared<const std::vector<hal::Frame>>(std::move(f));
            enter(state, "measuring " + std::to_string(frames->size()) + " photo(s)");
            MeasureInput input{
                frames, read("camera.yaml").value_or(""), read("plane.yaml").value_or(""),
                record_name(state == CycleState::verify ? what + "-overlay.png" : "overlay.png")};
            auto measure = [this, input = std::move(input), then] { mode_->measure(input, then); };
            if (!settings_.records.keep_photos) {
                measure();
                return;
            }
            // The photos join the record when the configuration says so, encoded off the loop.
            auto photos = std::make_shared<std::vector<std::string>>();
            work(
                [frames, photos] {
                    for (const auto& frame : *frames) photos->push_back(png_of(frame));
                },
                [this, photos, what, measure = std::move(measure)] {
                    for (std::size_t i = 0; i < photos->size(); ++i)
                        if (!keep(record_name(what + "-photo-" + std::to_string(i + 1) + ".png"),
                                  (*photos)[i]))
                            return;
                    measure();
                });
        });
}

void Cycle::solve() {
    mode_->solve([this](SolveOutcome outcome) {
        // A later pass's measurement is the verification print of the one before.
        if (!report_.measured) {
            report_.measured = outcome.measured;
            report_.in_force = outcome.in_force;
        }
        switch (outcome.next) {
            case SolveOutcome::Next::review:
                review();
                return;
            case SolveOutcome::Next::apply:
                apply();
                return;
            case SolveOutcome::Next::done:
                finish_cycle();
                return;
        }
    });
}

void Cycle::review() {
    const ReviewText text = mode_->review();
    enter(CycleState::review, text.detail);
    log(text.proposed);
    for (const auto& line : text.details) log_detail(line);
    show(draw_screen(text.screen));
    ask(Prompt::review, 0, [this] { apply(); });
}

void Cycle::apply() {
    mode_->apply([this](bool verify_next) {
        report_.applied = verify_next;
        if (verify_next)
            verify();
        else
            finish_cycle();
    });
}

void Cycle::verify() {
    enter(CycleState::verify, mode_->verify_detail());
    ask(Prompt::clear_bed, 0, [this] {
        mode_->verification_job(target_job_, [this](const std::vector<std::string>& job) {
            run_job(job, [this](const JobOutcome&) {
                measure_print(CycleState::verify, [this] {
                    mode_->judge_verification([this](VerifyOutcome outcome) {
                        report_.verified = outcome.verified;
                        if (outcome.solve_again) {
                            solve();
                            return;
                        }
                        finish_cycle();
                    });
                });
            });
        });
    });
}

std::string Cycle::revert() {
    if (state_ != CycleState::idle)
        return "revert: the box is busy (" + std::string(state_name(state_)) + ")";
    const auto last = read("last-cycle");
    if (!last) return "revert: no cycle has run here";
    const int number = std::atoi(last->c_str());
    report_ = CycleReport{};
    report_.number = number;
    error_.clear();
    mode_->begin();
    std::string refused = mode_->revert(number, [this](const std::string& what) {
        enter(CycleState::idle, what);
        tell(&CycleNews::cycle_end, true);
    });
    if (!refused.empty()) return refused;
    return state_ == CycleState::error ? error_ : std::string();
}

bool Cycle::goal_met() const {
    return completed_ > 0 && report_.verified &&
           mode_->goal().met(report_.measured.value_or(modes::ErrorFigures{}), *report_.verified);
}

void Cycle::finish_cycle() {
    if (!keep("last-cycle", std::to_string(report_.number) + "\n")) return;
    const double total = seconds(d_.clock.now() - cycle_started_);
    log_("cycle " + std::to_string(report_.number) + ": done in " + number_text("%.1f", total) +
         " s: the box's own work " + number_text("%.2f", report_.box_seconds) + " s, camera " +
         number_text("%.2f", report_.camera_seconds) + " s, machine " +
         number_text("%.2f", report_.machine_seconds) + " s");
    ++completed_;
    enter(CycleState::idle,
          report_.verified
              // The statistic named, and the mean where the verification has one: the figure
              // the line before it ("verified ... mm mean") said.
              ? (report_.verified->mean_mm
                     ? "done: verified XY " + number_text("%.4f", *report_.verified->mean_mm) +
                           " mm mean, " + number_text("%.4f", report_.verified->rms_mm) + " mm RMS"
                     : "done: verified XY " + number_text("%.4f", report_.verified->rms_mm) +
                           " mm RMS")
              : "done");
    last_stage_seconds_ = stage_seconds_;
    if (report_.measured && report_.verified)
        show(draw_screen(DoneScreen{number_text("%.4f", report_.measured->rms_mm) + " mm",
                                    number_text("%.4f", report_.verified->rms_mm) + " mm"}));
    close_record();
    tell(&CycleNews::cycle_end, true);
}

void watch_cycle(EventLoop& loop, Cycle& cycle, MachineLink& machine, hal::Camera& camera,
                 hal::Lines& lines) {
    machine.attach(loop);
    loop.watch(lines.button_fd(), [&cycle] { cycle.on_button(); });
    loop.watch(camera.completion_fd(), [&cycle] { cycle.on_camera(); });
    loop.watch(cycle.blink_fd(), [&cycle] { cycle.on_blink(); });
}

}  // namespace calbox::firmware
