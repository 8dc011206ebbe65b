#include "firmware/cycle.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include "core/geometry/calibration.hpp"
#include "core/models/delta_commands.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/modes/delta_records.hpp"
#include "core/number_text.hpp"
#include "core/targets/compensate.hpp"
#include "core/targets/delta_target.hpp"
#include "core/targets/galvo_target.hpp"
#include "core/targets/job.hpp"
#include "core/targets/planar_target.hpp"
#include "core/vision/reference_marks.hpp"
#include "firmware/overlays.hpp"
#include "firmware/png.hpp"
#include "firmware/screens.hpp"

namespace calbox::firmware {
namespace {

double seconds(std::chrono::nanoseconds d) {
    return std::chrono::duration<double>(d).count();
}

std::string fixed(double v, int decimals) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", decimals, v);
    return b;
}

vision::GrayView view_of(const hal::Frame& f) {
    return {f.pixels.data(), f.width_px, f.height_px, f.stride_bytes};
}

// Photos from files or another camera: the lens model holds only at the size it was calibrated
// at.
vision::GrayView calibrated_view_of(const hal::Frame& frame, const geometry::CameraModel& camera) {
    if (frame.width_px != camera.image_width || frame.height_px != camera.image_height) {
        throw std::runtime_error("the photo is " + std::to_string(frame.width_px) + "x" +
                                 std::to_string(frame.height_px) +
                                 ", the camera was calibrated at " +
                                 std::to_string(camera.image_width) + "x" +
                                 std::to_string(camera.image_height) + " (camera.yaml)");
    }
    return view_of(frame);
}

std::string record_name(int cycle, const char* what) {
    char b[64];
    std::snprintf(b, sizeof b, "cycle-%04d-%s", cycle, what);
    return b;
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

// The lines as a file's text: each one ended by a newline.
std::string joined(const std::vector<std::string>& lines) {
    std::string out;
    for (const auto& l : lines) out += l + "\n";
    return out;
}

// "M665 M666": commands named in a message.
std::string spaced(const std::vector<std::string>& words) {
    std::string out;
    for (const auto& w : words) out += (out.empty() ? "" : " ") + w;
    return out;
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

Cycle::Cycle(CycleDevices devices, models::MachineFile machine, CycleSettings settings, Log log)
    : d_(devices),
      machine_(std::move(machine)),
      settings_(std::move(settings)),
      log_(std::move(log)),
      blink_(d_.clock.make_timer()) {
    if (!machine_.is_delta() && !machine_.is_galvo() && !machine_.is_planar())
        throw std::invalid_argument("the cycle runs the delta, galvo and planar modes, not a " +
                                    machine_.kind);
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
    if (on_state) on_state(next);
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
        if (!failed) log_(std::string(what) + ": " + e.what() + " (the box goes on without it)");
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
            d_.data.replace_file(record_name(report_.number, what), png_of(cycle_screens_[i]));
        }
        prune_records();
    } catch (const std::runtime_error& e) {
        log_("cycle " + std::to_string(report_.number) + ": records: " + e.what());
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
    IdleScreen idle{machine_.kind + " " + machine_.firmware, "no cycle yet"};
    if (completed_ > 0 && report_.measured_xy_rms_mm && report_.verify_xy_rms_mm)
        idle.last_result = "last " + fixed(*report_.measured_xy_rms_mm, 3) + " -> " +
                           fixed(*report_.verify_xy_rms_mm, 3) + " mm";
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
    if (on_prompt) on_prompt(prompt, step);
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
    if (on_cycle_end) on_cycle_end(false);
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
    log_("cycle " + std::to_string(report_.number) + ": error: " + message);
    state_ = CycleState::error;
    prompt_ = Prompt::acknowledge_error;
    set_leds();
    show(draw_screen(ErrorScreen{static_cast<int>(failed_in_),
                                 hint.empty() ? hint_for(failed_in_) : hint, message}));
    if (on_state) on_state(state_);
    close_record();
    if (on_cycle_end) on_cycle_end(false);
    if (on_prompt) on_prompt(prompt_, 0);
}

void Cycle::capture(int frames, std::function<void(std::vector<hal::Frame>)> then) {
    const unsigned generation = generation_;
    d_.lines.set_light(true);
    phase_started_ = d_.clock.now();
    d_.camera.start_capture({frames, {}, {}});
    // on_camera() continues; the continuation checks the generation.
    pending_capture_ = [this, generation, then = std::move(then)](std::vector<hal::Frame> f) {
        if (current(generation)) then(std::move(f));
    };
}

void Cycle::on_camera() {
    hal::CaptureResult result = d_.camera.take_frames();
    report_.camera_seconds += seconds(d_.clock.now() - phase_started_);
    d_.lines.set_light(false);
    auto then = std::move(pending_capture_);
    pending_capture_ = nullptr;
    if (!then) return;  // a capture the cycle no longer waits for
    if (!result.ok()) {
        if (state_ != CycleState::idle && state_ != CycleState::error) fail(result.error);
        return;
    }
    then(std::move(result.frames));
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

void Cycle::run_job(const std::vector<std::string>& lines, std::function<void(JobOutcome)> then) {
    const unsigned generation = generation_;
    const auto started = d_.clock.now();
    d_.machine.start_job(lines,
                         [this, generation, started, then = std::move(then)](JobOutcome outcome) {
                             if (!current(generation)) return;
                             report_.machine_seconds += seconds(d_.clock.now() - started);
                             if (!outcome.ok) {
                                 fail("machine: " + outcome.error);
                                 return;
                             }
                             then(std::move(outcome));
                         });
}

std::string Cycle::calibrate_camera() {
    if (state_ != CycleState::idle) return std::string("busy: ") + state_name(state_);
    take_next_settings();
    error_.clear();
    setup_only_ = true;
    calibration_views_.clear();
    setup_coverage_ = 0;
    enter(CycleState::setup_camera, "set-up: calibrating the camera from " +
                                        std::to_string(settings_.calibration_views) + " views of " +
                                        settings_.calibration_pattern);
    setup_camera_view(0);
    return {};
}

std::string Cycle::take_plane() {
    if (state_ != CycleState::idle) return std::string("busy: ") + state_name(state_);
    if (!d_.data.read_file("camera.yaml"))
        return "the camera is not calibrated yet: camera calibrate first";
    take_next_settings();
    error_.clear();
    setup_only_ = true;
    enter(CycleState::setup_plane, "set-up: the bed plane");
    setup_plane();
    return {};
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

void Cycle::notice(const std::string& what) {
    log_("cycle " + std::to_string(report_.number) + ": " + what);
    if (on_notice) on_notice(what);
}

void Cycle::begin_cycle() {
    take_next_settings();
    stage_seconds_ = {};
    cycle_screens_.clear();
    report_ = CycleReport{};
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

void Cycle::setup_camera_view(int view) {
    ask(Prompt::hold_calibration_board, view, [this, view] {
        capture(1, [this, view](std::vector<hal::Frame> frames) {
            // Each view's board is found as it is taken, so that the person knows at once
            // whether it counted and how much of the image the views cover so far.
            auto frame = std::make_shared<hal::Frame>(std::move(frames.front()));
            auto found = std::make_shared<std::optional<geometry::BoardObservation>>();
            work(
                [frame, found, pattern = settings_.calibration_pattern] {
                    *found = geometry::find_board(geometry::parse_pattern_spec(pattern),
                                                  view_of(*frame));
                },
                [this, view, frame, found] { take_calibration_view(view, *frame, *found); });
        });
    });
}

void Cycle::take_calibration_view(int view, const hal::Frame& frame,
                                  const std::optional<geometry::BoardObservation>& found) {
    const std::string of =
        std::to_string(view + 1) + "/" + std::to_string(settings_.calibration_views);
    if (!found) {
        notice("view " + of + ": no board found; hold it fully in view and press again");
        setup_camera_view(view);
        return;
    }
    image_size_ = {frame.width_px, frame.height_px};
    calibration_views_.push_back({"view " + std::to_string(view + 1), *found});
    setup_coverage_ = geometry::image_coverage(calibration_views_, frame.width_px, frame.height_px);
    notice("view " + of + ": " + std::to_string(found->image_points.size()) + " corners, " +
           std::to_string(static_cast<int>(std::lround(100 * setup_coverage_))) +
           " % of the image covered");
    if (view + 1 < settings_.calibration_views) {
        setup_camera_view(view + 1);
        return;
    }
    auto yaml = std::make_shared<std::string>();
    auto summary = std::make_shared<std::string>();
    auto views =
        std::make_shared<std::vector<geometry::ObservedView>>(std::move(calibration_views_));
    calibration_views_.clear();
    work(
        [views, yaml, summary, size = image_size_] {
            const auto result = geometry::calibrate_from_views(geometry::LensModel::pinhole, *views,
                                                               size[0], size[1]);
            std::vector<double> per_view;
            for (const auto& v : result.views) per_view.push_back(v.rms_px);
            *yaml = geometry::camera_to_yaml(result.camera, per_view);
            *summary = "camera calibrated from " + std::to_string(result.views.size()) +
                       " views, RMS " + fixed(result.camera.rms_px, 3) + " px";
        },
        [this, yaml, summary] {
            if (!keep("camera.yaml", *yaml)) return;
            // A new camera model makes the old plane's pose stale: the plane is taken again.
            try {
                d_.data.remove_file("plane.yaml");
            } catch (const std::runtime_error& e) {
                fail(std::string("records: ") + e.what());
                return;
            }
            notice(*summary);
            enter(CycleState::setup_plane, "set-up: the bed plane");
            setup_plane();
        });
}

void Cycle::setup_plane() {
    ask(Prompt::lay_plane_board, 0, [this] {
        capture(1, [this](std::vector<hal::Frame> frames) {
            auto frame = std::make_shared<hal::Frame>(std::move(frames.front()));
            auto yaml = std::make_shared<std::string>();
            auto reference_yaml = std::make_shared<std::string>();
            auto summary = std::make_shared<std::string>();
            const std::string camera_yaml = d_.data.read_file("camera.yaml").value_or("");
            work(
                [frame, yaml, reference_yaml, summary, camera_yaml,
                 pattern = settings_.plane_pattern, thickness = settings_.plane_board_thickness_mm,
                 marks = settings_.reference_marks] {
                    const auto camera = geometry::camera_from_yaml(camera_yaml);
                    const auto plane = geometry::estimate_bed_plane(
                        camera, geometry::parse_pattern_spec(pattern), view_of(*frame), thickness);
                    *yaml = geometry::plane_to_yaml(plane);
                    *summary =
                        "bed plane from " + pattern + ", RMS " + fixed(plane.rms_px, 3) + " px";
                    if (marks == kNoReferenceMarks) return;
                    // The marks' view is taken with the plane, in the same photo: the two hold
                    // together until the camera moves.
                    const auto reference =
                        vision::find_reference_marks(view_of(*frame), marks, camera);
                    if (static_cast<int>(reference.marks.size()) < kMinimumReferenceMarks) {
                        throw geometry::CalibrationError(
                            std::to_string(reference.marks.size()) + " of the at least " +
                            std::to_string(kMinimumReferenceMarks) + " fixed reference marks (" +
                            marks +
                            ") in view: stick them on the frame or the bed outside the work area "
                            "and clear of the board, or set setup.reference_marks = none to run "
                            "without the camera check");
                    }
                    *reference_yaml = vision::reference_to_yaml(reference);
                    *summary += ", " + std::to_string(reference.marks.size()) + " reference marks";
                },
                [this, yaml, reference_yaml, summary] {
                    // The plane last: a plane on file always has its marks' view beside it.
                    try {
                        if (reference_yaml->empty()) d_.data.remove_file(kReferenceFile);
                    } catch (const std::runtime_error& e) {
                        fail(std::string("records: ") + e.what());
                        return;
                    }
                    if (!reference_yaml->empty() && !keep(kReferenceFile, *reference_yaml)) return;
                    if (!keep("plane.yaml", *yaml)) return;
                    notice(*summary);
                    if (setup_only_) {
                        setup_only_ = false;
                        enter(CycleState::idle, "set-up done: " + *summary);
                        return;
                    }
                    ask_clear_bed_then_target();
                });
        });
    });
}

void Cycle::check_camera() {
    if (settings_.reference_marks == kNoReferenceMarks) {
        ask_clear_bed_then_target();
        return;
    }
    const auto stored = d_.data.read_file(kReferenceFile);
    if (!stored) {
        enter(CycleState::setup_plane, "set-up: checking the camera");
        fail("the camera check: no stored view of the reference marks (" +
                 std::string(kReferenceFile) +
                 "); take the plane again (console: camera plane) with the marks in view",
             "take the plane again");
        return;
    }
    enter(CycleState::setup_plane, "set-up: checking the camera against the reference marks");
    capture(1, [this, stored = *stored](std::vector<hal::Frame> frames) {
        auto frame = std::make_shared<hal::Frame>(std::move(frames.front()));
        auto move = std::make_shared<vision::CameraMove>();
        work(
            [frame, move, stored, camera_yaml = d_.data.read_file("camera.yaml").value_or(""),
             plane_yaml = d_.data.read_file("plane.yaml").value_or("")] {
                const auto reference = vision::reference_from_yaml(stored);
                const auto camera = geometry::camera_from_yaml(camera_yaml);
                *move = vision::compare_reference(
                    reference,
                    vision::find_reference_marks(calibrated_view_of(*frame, camera),
                                                 reference.dictionary, camera),
                    camera, geometry::plane_from_yaml(plane_yaml));
            },
            [this, move] {
                const std::string seen =
                    std::to_string(move->marks_compared) + " of " +
                    std::to_string(move->marks_compared + static_cast<int>(move->missing.size())) +
                    " reference marks";
                if (move->marks_compared < kMinimumReferenceMarks || !move->missing.empty()) {
                    std::string ids;
                    for (int id : move->missing)
                        ids += (ids.empty() ? "" : ", ") + std::to_string(id);
                    fail("the camera check: " + seen + " found (missing: " + ids +
                             "); the camera has moved or a mark is covered: uncover the marks or "
                             "take the plane again (console: camera plane)",
                         "marks hidden or moved");
                    return;
                }
                report_.camera_move_mm = move->largest_mm;
                const std::string moved = "largest apparent move " + fixed(move->largest_mm, 3) +
                                          " mm (limit " +
                                          fixed(settings_.camera_moved_limit_mm, 3) + " mm)";
                if (move->largest_mm > settings_.camera_moved_limit_mm) {
                    fail("the camera has moved since the plane was taken: " + seen + ", " + moved +
                             "; fix the camera's mount, then take the plane again (console: "
                             "camera plane)",
                         "camera moved: replane");
                    return;
                }
                notice("camera check: " + seen + ", " + moved);
                ask_clear_bed_then_target();
            });
    });
}

void Cycle::ask_clear_bed_then_target() {
    enter(CycleState::make_target, "the " + machine_.kind + " target for " + machine_.firmware);
    ask(Prompt::clear_bed, 0, [this] { make_target(); });
}

void Cycle::make_target() {
    auto lines = std::make_shared<std::vector<std::string>>();
    work(
        [machine = machine_, lines] {
            std::istringstream text(
                machine.is_planar()
                    ? targets::make_planar_target(machine).job
                    : targets::write_gcode(machine.is_galvo()
                                               ? targets::make_galvo_target(machine).job
                                               : targets::make_delta_target(machine).job,
                                           machine, "calbox target"));
            std::string line;
            while (std::getline(text, line)) lines->push_back(line);
        },
        [this, lines] {
            target_job_ = *lines;
            auto make = [this] {
                enter(CycleState::wait_machine,
                      "making the target: " + std::to_string(target_job_.size()) + " lines");
                run_job(target_job_, [this](const JobOutcome&) {
                    enter(CycleState::capture,
                          std::to_string(settings_.frames_per_capture) + " frame(s)");
                    measure_print(CycleState::measure, [this] {
                        if (measurements_) {
                            const auto errors = modes::placement_errors(measurements_->features);
                            report_.measured_xy_rms_mm = errors.rms_mm;
                            report_.measured_xy_max_mm = errors.largest_mm;
                        }
                        solve();
                    });
                });
            };
            // A galvo or a router has no geometry settings to read: its correction is the box's.
            if (keeps_correction()) {
                make();
            } else {
                read_printer_settings([this, make = std::move(make)] { probe_printer(make); });
            }
        });
}

// The correction is worked out from the settings in force, which an earlier cycle, a revert or
// the owner may have changed since the machine file was written: they are read from the printer.
// Klipper's live in printer.cfg, out of the link's reach: the machine file's stand.
void Cycle::read_printer_settings(std::function<void()> then) {
    if (machine_.firmware == "klipper") {
        then();
        return;
    }
    read_settings(machine_.firmware,
                  [this, then = std::move(then)](const std::vector<std::string>& commands) {
                      try {
                          machine_.delta =
                              models::geometry_from_settings(machine_.firmware, commands);
                      } catch (const std::exception& e) {
                          fail("the printer's reply to " +
                               spaced(models::settings_query(machine_.firmware)) + ": " + e.what());
                          return;
                      }
                      log_("cycle " + std::to_string(report_.number) +
                           ": the printer's settings: " + spaced(commands));
                      then();
                  });
}

void Cycle::probe_printer(std::function<void()> then) {
    probe_.clear();
    if (!machine_.probe) {
        then();
        return;
    }
    const auto points = modes::probe_points(*machine_.probe);
    enter(CycleState::wait_machine,
          "the printer probes the bed: " + std::to_string(points.size()) + " points");
    run_job(modes::probe_job(machine_.firmware, points),
            [this, points, then = std::move(then)](const JobOutcome& outcome) {
                try {
                    probe_ = modes::probe_from_replies(machine_.firmware, points, outcome.replies,
                                                       machine_.probe->repeatability_mm);
                } catch (const std::invalid_argument& e) {
                    fail(std::string("the printer's probe report: ") + e.what());
                    return;
                }
                double low = 1e9, high = -1e9;
                for (const auto& p : probe_) {
                    low = std::min(low, p.z_mm);
                    high = std::max(high, p.z_mm);
                }
                if (!keep(record_name(report_.number, "probe.csv"), modes::probe_to_csv(probe_)))
                    return;
                log_("cycle " + std::to_string(report_.number) + ": the printer's probe: " +
                     std::to_string(probe_.size()) + " points, the nozzle's gap ranging " +
                     number_text("%.3f", high - low) + " mm over the bed");
                then();
            });
}

void Cycle::read_settings(const std::string& firmware,
                          std::function<void(std::vector<std::string>)> then) {
    run_job(models::settings_query(firmware),
            [firmware, then = std::move(then)](const JobOutcome& outcome) {
                then(models::settings_from_report(firmware, outcome.replies));
            });
}

void Cycle::send_and_read_back(const std::string& firmware, const std::vector<std::string>& lines,
                               std::function<void(std::string, std::vector<std::string>)> then) {
    run_job(lines, [this, firmware, lines, then = std::move(then)](const JobOutcome&) {
        read_settings(firmware, [firmware, lines, then](std::vector<std::string> reported) {
            // Compared before the report is moved on (argument order is unspecified).
            std::string mismatch = models::settings_mismatch(firmware, lines, reported);
            then(std::move(mismatch), std::move(reported));
        });
    });
}

// Photographs what was printed and measures it into measurements_.
void Cycle::measure_print(CycleState state, std::function<void()> then) {
    capture(settings_.frames_per_capture, [this, state,
                                           then = std::move(then)](std::vector<hal::Frame> f) {
        auto frames = std::make_shared<std::vector<hal::Frame>>(std::move(f));
        enter(state, "measuring " + std::to_string(frames->size()) + " photo(s)");
        auto record = std::make_shared<modes::DeltaMeasurementsRecord>();
        auto galvo = std::make_shared<modes::GalvoMeasurement>();
        auto planar = std::make_shared<modes::PlanarMeasurement>();
        const std::string camera_yaml = d_.data.read_file("camera.yaml").value_or("");
        const std::string plane_yaml = d_.data.read_file("plane.yaml").value_or("");
        // The photos join the record when the configuration says so, encoded off the loop.
        auto photos = std::make_shared<std::vector<std::string>>();
        auto overlay = std::make_shared<std::string>();  // what was found, on the first photo
        work(
            [machine = machine_, frames, record, galvo, planar, camera_yaml, plane_yaml, photos,
             overlay, keep_photos = settings_.records.keep_photos] {
                if (keep_photos)
                    for (const auto& frame : *frames) photos->push_back(png_of(frame));
                const auto camera = geometry::camera_from_yaml(camera_yaml);
                const auto plane = geometry::plane_from_yaml(plane_yaml);
                std::vector<vision::GrayView> views;
                for (const auto& frame : *frames)
                    views.push_back(calibrated_view_of(frame, camera));
                std::vector<std::string> names;
                for (std::size_t i = 0; i < frames->size(); ++i)
                    names.push_back("frame " + std::to_string(i + 1));
                if (machine.is_galvo()) {
                    // One photo of the whole grid: the first frame.
                    *galvo = modes::measure_galvo(machine, camera, plane, views.front());
                    galvo->photos = {names.front()};
                    *overlay = galvo_overlay_png(views.front(), *galvo, machine, camera, plane);
                    return;
                }
                if (machine.is_planar()) {
                    // The box's camera sees the whole sheet: the first frame.
                    *planar = modes::measure_planar(machine, camera, plane, views.front());
                    planar->photos = {names.front()};
                    *overlay = planar_overlay_png(views.front(), *planar, machine, camera, plane);
                    return;
                }
                const auto measured = modes::measure_delta(machine, camera, plane, views);
                *record = modes::record_of(measured, machine, names);
                *overlay = delta_overlay_png(views.front(), measured, camera, plane);
            },
            [this, record, galvo, planar, then, photos, overlay, state] {
                const bool verifying = state == CycleState::verify;
                if (!keep(verifying ? pass_file("verify-overlay.png")
                                    : record_name(report_.number, "overlay.png"),
                          *overlay))
                    return;
                for (std::size_t i = 0; i < photos->size(); ++i) {
                    const std::string what = std::string(verifying ? "verify" : "target") +
                                             "-photo-" + std::to_string(i + 1) + ".png";
                    if (!keep(verifying ? pass_file(what.c_str())
                                        : record_name(report_.number, what.c_str()),
                              (*photos)[i]))
                        return;
                }
                if (machine_.is_galvo()) {
                    galvo_measured_ = *galvo;
                } else if (machine_.is_planar()) {
                    planar_measured_ = *planar;
                } else {
                    measurements_ = *record;
                }
                then();
            });
    });
}

void Cycle::solve() {
    if (machine_.is_galvo()) {
        solve_galvo();
        return;
    }
    if (machine_.is_planar()) {
        solve_planar();
        return;
    }
    // A later pass measures the verification print, kept as the pass before's.
    const int pass = static_cast<int>(report_.passes.size()) + 1;
    if (pass == 1 && !keep(record_name(report_.number, "measurements.json"),
                           modes::measurements_to_json(*measurements_)))
        return;
    enter(CycleState::solve, (pass > 1 ? "pass " + std::to_string(pass) + ": " : std::string()) +
                                 std::to_string(measurements_->features.size()) + " corners");
    auto solution = std::make_shared<modes::DeltaSolution>();
    // The probe measured the printer as the first pass found it.
    auto probe = pass == 1 ? probe_ : std::vector<solve::ProbePoint>{};
    work([machine = machine_, measurements = *measurements_, options = settings_.solve, solution,
          probe = std::move(
              probe)] { *solution = modes::solve_delta(machine, measurements, probe, options); },
         [this, solution, pass] {
             DeltaPassReport p;
             p.pass = pass;
             // What the pass measured was placed already: the cycle's first print, or the
             // verification print of the pass before.
             p.measured_xy_rms_mm = pass == 1 ? report_.measured_xy_rms_mm.value()
                                              : report_.passes.back().verify_xy_rms_mm.value();
             p.measured_xy_max_mm = pass == 1 ? report_.measured_xy_max_mm.value()
                                              : report_.passes.back().verify_xy_max_mm.value();
             const auto& c = solution->fit.correction;
             p.gap_range_mm = c.predicted_height_range_now_mm;
             p.xy_change_mm = c.predicted_xy_change_mm;
             p.height_change_mm = c.predicted_height_change_mm;
             p.step = modes::next_delta_pass_step(*solution, pass, settings_.passes);
             report_.passes.push_back(p);
             if (!keep(pass_file("result.json"), modes::result_to_json(*solution))) return;
             log_("cycle " + std::to_string(report_.number) + ": " +
                  modes::describe_delta_pass(*solution, pass, p.step, settings_.passes));
             // A printer that holds keeps the correction in force: the report's stays the one sent.
             if (p.step == modes::DeltaPassStep::holds) {
                 finish_cycle();
                 return;
             }
             report_.solution = *solution;
             // The owner reviewed the cycle's correction at its first pass; a later one is the
             // same calibration carried on (within the same bounds), applied as it comes so
             // that a button or a PLC confirms a cycle once.
             if (pass > 1) {
                 for (const auto& command : solution->commands) log_("  " + command);
                 apply();
                 return;
             }
             review();
         });
}

std::string Cycle::pass_file(const char* what) const {
    const std::size_t pass = std::max<std::size_t>(report_.passes.size(), 1);
    return record_name(
        report_.number,
        (pass == 1 ? std::string(what) : "pass-" + std::to_string(pass) + "-" + what).c_str());
}

void Cycle::review() {
    if (machine_.is_galvo()) {
        review_galvo();
        return;
    }
    if (machine_.is_planar()) {
        review_planar();
        return;
    }
    const auto& s = *report_.solution;
    const auto& before = s.fit.fitted.before;
    const auto& c = s.fit.correction;
    const auto& pass = report_.passes.back();
    enter(CycleState::review, "predicted XY after " + fixed(c.predicted_xy_rms_mm, 4) + " mm RMS");
    log_("cycle " + std::to_string(report_.number) + ": proposed: rod " +
         fixed(before.diagonal_rod_mm, 3) + " -> " + fixed(s.after.diagonal_rod_mm, 3) +
         " mm, radius " + fixed(before.radius_mm, 3) + " -> " + fixed(s.after.radius_mm, 3) +
         " mm; fit RMS " + fixed(s.fit.fitted.fit_rms_mm, 4) + " mm; predicted XY " +
         fixed(c.predicted_xy_rms_mm, 4) + " mm RMS, " + fixed(c.predicted_xy_max_mm, 4) +
         " mm worst");
    for (const auto& command : s.commands) log_("  " + command);
    show(draw_screen(ReviewScreen{
        {"rod " + number_text("%+.3f", s.after.diagonal_rod_mm - before.diagonal_rod_mm) + " mm",
         "radius " + number_text("%+.3f", s.after.radius_mm - before.radius_mm) + " mm"},
        "XY " + fixed(pass.measured_xy_rms_mm, 3),
        fixed(c.predicted_xy_rms_mm, 3) + " mm"}));
    ask(Prompt::review, 0, [this] { apply(); });
}

void Cycle::apply() {
    if (machine_.is_galvo()) {
        apply_galvo();
        return;
    }
    if (machine_.is_planar()) {
        apply_planar();
        return;
    }
    const auto& s = *report_.solution;
    if (s.firmware == "klipper") {
        // Klipper's geometry lives in printer.cfg: shown and stored, never pretended applied.
        if (!keep(record_name(report_.number, "printer.cfg"), joined(s.commands))) return;
        enter(CycleState::apply, "Klipper: edit printer.cfg as " +
                                     record_name(report_.number, "printer.cfg") + " says");
        finish_cycle();
        return;
    }
    enter(CycleState::apply,
          "backing up the settings (" + spaced(models::settings_query(s.firmware)) + ")");
    read_settings(s.firmware, [this](std::vector<std::string> backup) {
        report_.backup = std::move(backup);
        if (report_.backup.size() != 2) {
            fail("apply: the printer's reply to " +
                 spaced(models::settings_query(report_.solution->firmware)) +
                 " does not hold both its M665 and M666 settings to back up");
            return;
        }
        // Each pass backs up what it changes; revert goes back to before the cycle (pass 1's).
        if (!keep(pass_file("backup.gcode"), joined(report_.backup) + "M500\n")) return;
        const auto& solution = *report_.solution;
        log_("cycle " + std::to_string(report_.number) + ": sending " +
             std::to_string(solution.commands.size()) + " lines");
        send_and_read_back(solution.firmware, solution.commands,
                           [this](const std::string& mismatch, const std::vector<std::string>&) {
                               if (mismatch.empty()) {
                                   report_.applied = true;
                                   machine_.delta = report_.solution->after;
                                   verify();
                                   return;
                               }
                               restore_backup("apply: read-back mismatch: " + mismatch);
                           });
    });
}

// Puts back what was there, then stops with the reason.
void Cycle::restore_backup(const std::string& why) {
    auto restore = report_.backup;
    restore.emplace_back("M500");
    log_("cycle " + std::to_string(report_.number) + ": " + why + "; restoring the backup");
    run_job(restore, [this, why](const JobOutcome&) {
        fail(why + " (the previous settings were restored)");
    });
}

std::string Cycle::revert() {
    if (state_ != CycleState::idle)
        return "revert: the box is busy (" + std::string(state_name(state_)) + ")";
    if (machine_.firmware == "klipper")
        return "revert: Klipper's settings live in printer.cfg; the box never changed them";
    const auto last = d_.data.read_file("last-cycle");
    if (!last) return "revert: no cycle has run here";
    const int number = std::atoi(last->c_str());
    if (keeps_correction()) {
        // The correction is the box's own file: the one in force before goes back.
        const std::string backup_name = record_name(number, kept_backup_name());
        const auto kept = d_.data.read_file(backup_name);
        if (!kept)
            return "revert: cycle " + std::to_string(number) + " applied nothing (no " +
                   backup_name + ")";
        report_ = CycleReport{};
        report_.number = number;
        error_.clear();
        enter(CycleState::apply,
              "reverting to the correction in force before cycle " + std::to_string(number));
        if (!keep(kept_file(), *kept)) return error_;
        enter(CycleState::idle, "reverted to " + backup_name);
        if (on_cycle_end) on_cycle_end(true);
        return "";
    }
    const std::string name = record_name(number, "backup.gcode");
    const auto backup = d_.data.read_file(name);
    if (!backup)
        return "revert: cycle " + std::to_string(number) + " applied nothing (no " + name + ")";
    std::vector<std::string> lines;
    std::istringstream text(*backup);
    for (std::string line; std::getline(text, line);)
        if (!line.empty()) lines.push_back(line);
    report_ = CycleReport{};
    report_.number = number;
    error_.clear();
    enter(CycleState::apply,
          "reverting to the settings saved before cycle " + std::to_string(number));
    send_and_read_back(
        machine_.firmware, lines,
        [this, name](const std::string& mismatch, const std::vector<std::string>& reported) {
            if (!mismatch.empty()) {
                fail("revert: read-back mismatch: " + mismatch);
                return;
            }
            machine_.delta = models::geometry_from_settings(machine_.firmware, reported);
            enter(CycleState::idle, "reverted to " + name);
            if (on_cycle_end) on_cycle_end(true);
        });
    return "";
}

void Cycle::verify() {
    if (machine_.is_galvo()) {
        verify_galvo();
        return;
    }
    if (machine_.is_planar()) {
        verify_planar();
        return;
    }
    enter(CycleState::verify, "printing the target again on the corrected machine");
    ask(Prompt::clear_bed, 0, [this] {
        run_job(target_job_, [this](const JobOutcome&) {
            measure_print(CycleState::verify, [this] {
                const auto errors = modes::placement_errors(measurements_->features);
                report_.verify_xy_rms_mm = errors.rms_mm;
                report_.verify_xy_max_mm = errors.largest_mm;
                if (!keep(pass_file("verify-measurements.json"),
                          modes::measurements_to_json(*measurements_)))
                    return;
                log_("cycle " + std::to_string(report_.number) +
                     ": verified on the re-printed target: XY " +
                     fixed(*report_.verify_xy_rms_mm, 4) + " mm RMS, " +
                     fixed(*report_.verify_xy_max_mm, 4) + " mm worst");
                auto& pass = report_.passes.back();
                pass.verify_xy_rms_mm = report_.verify_xy_rms_mm;
                pass.verify_xy_max_mm = report_.verify_xy_max_mm;
                if (pass.step == modes::DeltaPassStep::apply_then_measure_again) {
                    solve();  // the verification print, on the levelled bed, is the next pass
                    return;
                }
                if (pass.step == modes::DeltaPassStep::apply_and_stop_out_of_passes)
                    notice("pass " + std::to_string(pass.pass) +
                           ", the last allowed, still corrected the printer by up to " +
                           fixed(std::max(pass.xy_change_mm, pass.height_change_mm), 3) +
                           " mm; calibrate again to see whether it holds, and if it does not, "
                           "check that the bed is flat and firmly mounted");
                finish_cycle();
            });
        });
    });
}

void Cycle::solve_galvo() {
    if (!keep(record_name(report_.number, "measurements.json"),
              modes::galvo_measurements_to_json(*galvo_measured_)))
        return;
    enter(CycleState::solve, std::to_string(galvo_measured_->nodes.size()) + " marks, " +
                                 std::to_string(galvo_measured_->missing.size()) + " missing");
    auto solution = std::make_shared<modes::GalvoSolution>();
    work([machine = machine_, measured = *galvo_measured_,
          solution] { *solution = modes::solve_galvo(machine, measured, std::nullopt); },
         [this, solution] {
             report_.galvo = *solution;
             report_.measured_xy_rms_mm = solution->fit.before.rms_mm;
             report_.measured_xy_max_mm = solution->fit.before.max_mm;
             if (!keep(record_name(report_.number, "result.json"),
                       modes::galvo_result_to_json(*solution)))
                 return;
             if (!keep(record_name(report_.number, "table.csv"),
                       models::table_to_csv(solution->fit.table)))
                 return;
             review();
         });
}

void Cycle::review_galvo() {
    const auto& s = *report_.galvo;
    const auto& t = s.fit.table;
    enter(CycleState::review, "predicted after " + fixed(s.predicted_rms_mm, 4) + " mm RMS");
    log_("cycle " + std::to_string(report_.number) + ": proposed: a " + std::to_string(t.nodes) +
         " x " + std::to_string(t.nodes) + " table over X " + fixed(t.min_x_mm, 2) + ".." +
         fixed(t.max_x_mm, 2) + " Y " + fixed(t.min_y_mm, 2) + ".." + fixed(t.max_y_mm, 2) +
         " mm; error now " + fixed(s.fit.before.mean_mm, 4) + " mm mean, " +
         fixed(s.fit.before.max_mm, 4) + " mm worst; predicted after " +
         fixed(s.predicted_rms_mm, 4) + " mm RMS");
    show(draw_screen(
        ReviewScreen{{"a " + std::to_string(t.nodes) + "x" + std::to_string(t.nodes) + " table",
                      "mean error, in mm:"},
                     fixed(s.fit.before.mean_mm, 3),
                     fixed(s.predicted_rms_mm, 3)}));
    ask(Prompt::review, 0, [this] { apply(); });
}

// The box keeps the scanner's table (kGalvoTableFile) and sends jobs through it; the one in
// force before is kept with the cycle's record, so that revert can put it back.
void Cycle::apply_galvo() {
    enter(CycleState::apply, "keeping the table: jobs now go through it");
    const auto previous = d_.data.read_file(kGalvoTableFile);
    if (!keep(record_name(report_.number, kept_backup_name()), previous.value_or(kNoGalvoTable)))
        return;
    if (!keep(kGalvoTableFile, modes::galvo_result_to_json(*report_.galvo))) return;
    report_.applied = true;
    verify();
}

void Cycle::verify_galvo() {
    enter(CycleState::verify, "burning the grid again through the table");
    ask(Prompt::clear_bed, 0, [this] {
        auto lines = std::make_shared<std::vector<std::string>>();
        work(
            [job = target_job_, table = report_.galvo->fit.table, lines] {
                std::string text;
                for (const auto& l : job) text += l + "\n";
                targets::CompensateReport ignored;
                std::istringstream compensated(targets::compensate_gcode(
                    text, [&table](geometry::Point2 p) { return table.command_for(p); },
                    [&table](geometry::Point2 p) { return table.covers(p); }, {}, ignored));
                for (std::string line; std::getline(compensated, line);) lines->push_back(line);
            },
            [this, lines] {
                run_job(*lines, [this](const JobOutcome&) {
                    measure_print(CycleState::verify, [this] {
                        auto again = std::make_shared<modes::GalvoSolution>();
                        work([machine = machine_, measured = *galvo_measured_,
                              through = report_.galvo,
                              again] { *again = modes::solve_galvo(machine, measured, through); },
                             [this, again] {
                                 report_.verify_xy_rms_mm = again->fit.before.rms_mm;
                                 report_.verify_xy_max_mm = again->fit.before.max_mm;
                                 if (!keep(record_name(report_.number, "verify-measurements.json"),
                                           modes::galvo_measurements_to_json(*galvo_measured_)))
                                     return;
                                 // Its "before" is the table's verified "after".
                                 if (!keep(record_name(report_.number, "verify-result.json"),
                                           modes::galvo_result_to_json(*again)))
                                     return;
                                 log_("cycle " + std::to_string(report_.number) +
                                      ": verified on the grid burned through the table: " +
                                      fixed(again->fit.before.mean_mm, 4) + " mm mean, " +
                                      fixed(again->fit.before.rms_mm, 4) + " mm RMS, " +
                                      fixed(again->fit.before.max_mm, 4) + " mm worst");
                                 finish_cycle();
                             });
                    });
                });
            });
    });
}

namespace {

double rms_norm(const std::vector<geometry::Point2>& errors_mm) {
    double sum = 0;
    for (const auto& e : errors_mm) sum += e.x * e.x + e.y * e.y;
    return std::sqrt(sum / static_cast<double>(std::max<std::size_t>(1, errors_mm.size())));
}

}  // namespace

const char* Cycle::kept_file() const {
    return machine_.is_galvo() ? kGalvoTableFile : kPlanarResultFile;
}
const char* Cycle::kept_backup_name() const {
    return machine_.is_galvo() ? "backup-table.json" : "backup-result.json";
}

void Cycle::solve_planar() {
    if (!keep(record_name(report_.number, "measurements.json"),
              modes::planar_measurements_to_json(*planar_measured_)))
        return;
    enter(CycleState::solve, std::to_string(planar_measured_->holes.size()) + " holes, " +
                                 std::to_string(planar_measured_->missing.size()) + " missing");
    auto solution = std::make_shared<modes::PlanarSolution>();
    auto firmware = std::make_shared<modes::FirmwareSettings>();
    work(
        [machine = machine_, measured = *planar_measured_, solution, firmware] {
            *solution = modes::solve_planar(machine, measured);
            *firmware = modes::planar_firmware_settings(machine, *solution);
        },
        [this, solution, firmware] {
            report_.planar = *solution;
            report_.measured_xy_rms_mm = rms_norm(solution->error_mm);
            report_.measured_xy_max_mm = solution->before.max_mm;
            if (!keep(record_name(report_.number, "result.json"),
                      modes::planar_result_to_json(*solution, *firmware)))
                return;
            // The firmware's own knobs, for a person who would rather set them: shown, not sent
            // (the compensated jobs carry the whole model; both would correct twice).
            std::string lines;
            for (const auto& line : firmware->lines) lines += line + "\n";
            if (!keep(record_name(report_.number, "firmware.txt"), lines)) return;
            review();
        });
}

void Cycle::review_planar() {
    const auto& s = *report_.planar;
    enter(CycleState::review, "predicted after " + fixed(s.after.mean_mm, 4) + " mm mean");
    log_("cycle " + std::to_string(report_.number) + ": proposed: the error model over X " +
         fixed(s.min_x_mm, 1) + ".." + fixed(s.max_x_mm, 1) + " Y " + fixed(s.min_y_mm, 1) + ".." +
         fixed(s.max_y_mm, 1) + " mm; error norm now " + fixed(s.before.mean_mm, 4) + " mm mean, " +
         fixed(s.before.max_mm, 4) + " mm worst; predicted after " + fixed(s.after.mean_mm, 4) +
         " mm mean, " + fixed(s.after.max_mm, 4) + " mm worst");
    show(draw_screen(ReviewScreen{
        {"error model, " + std::to_string(s.fit.rank - 3) + " terms", "mean error, in mm:"},
        fixed(s.before.mean_mm, 3),
        fixed(s.after.mean_mm, 3)}));
    ask(Prompt::review, 0, [this] { apply(); });
}

// The box keeps the error model (kPlanarResultFile) and compensates jobs through it; the one in
// force before is kept with the cycle's record, so that revert can put it back.
void Cycle::apply_planar() {
    enter(CycleState::apply, "keeping the error model: jobs now go through it");
    const auto previous = d_.data.read_file(kPlanarResultFile);
    if (!keep(record_name(report_.number, kept_backup_name()), previous.value_or(kNoPlanarResult)))
        return;
    if (!keep(kPlanarResultFile,
              modes::planar_result_to_json(
                  *report_.planar, modes::planar_firmware_settings(machine_, *report_.planar))))
        return;
    report_.applied = true;
    verify();
}

void Cycle::verify_planar() {
    enter(CycleState::verify, "drilling the grid again through the error model");
    ask(Prompt::clear_bed, 0, [this] {
        auto lines = std::make_shared<std::vector<std::string>>();
        work(
            [job = target_job_, solution = *report_.planar, lines] {
                std::string text;
                for (const auto& l : job) text += l + "\n";
                targets::CompensateReport ignored;
                std::istringstream compensated(targets::compensate_gcode(
                    text,
                    [&solution](geometry::Point2 p) {
                        return modes::planar_command_for(solution, p);
                    },
                    [&solution](geometry::Point2 p) { return modes::planar_covers(solution, p); },
                    {}, ignored));
                for (std::string line; std::getline(compensated, line);) lines->push_back(line);
            },
            [this, lines] {
                run_job(*lines, [this](const JobOutcome&) {
                    measure_print(CycleState::verify, [this] {
                        auto again = std::make_shared<modes::PlanarSolution>();
                        work([machine = machine_, measured = *planar_measured_,
                              again] { *again = modes::solve_planar(machine, measured); },
                             [this, again] {
                                 // The holes drilled through the model against where they were
                                 // meant: the second solve's "before".
                                 const auto& v = again->before;
                                 report_.verify_xy_rms_mm = rms_norm(again->error_mm);
                                 report_.verify_xy_max_mm = v.max_mm;
                                 if (!keep(record_name(report_.number, "verify-measurements.json"),
                                           modes::planar_measurements_to_json(*planar_measured_)))
                                     return;
                                 log_("cycle " + std::to_string(report_.number) +
                                      ": verified on the grid drilled through the model: " +
                                      fixed(v.mean_mm, 4) + " mm mean, " + fixed(v.max_mm, 4) +
                                      " mm worst");
                                 finish_cycle();
                             });
                    });
                });
            });
    });
}

void Cycle::finish_cycle() {
    if (!keep("last-cycle", std::to_string(report_.number) + "\n")) return;
    const double total = seconds(d_.clock.now() - cycle_started_);
    log_("cycle " + std::to_string(report_.number) + ": done in " + fixed(total, 1) +
         " s: the box's own work " + fixed(report_.box_seconds, 2) + " s, camera " +
         fixed(report_.camera_seconds, 2) + " s, machine " + fixed(report_.machine_seconds, 2) +
         " s");
    ++completed_;
    enter(CycleState::idle, report_.verify_xy_rms_mm
                                ? "done: XY " + fixed(*report_.verify_xy_rms_mm, 3) + " mm"
                                : "done");
    last_stage_seconds_ = stage_seconds_;
    if (report_.measured_xy_rms_mm && report_.verify_xy_rms_mm)
        show(draw_screen(DoneScreen{fixed(*report_.measured_xy_rms_mm, 4) + " mm",
                                    fixed(*report_.verify_xy_rms_mm, 4) + " mm"}));
    close_record();
    if (on_cycle_end) on_cycle_end(true);
}

void watch_machine(EventLoop& loop, GcodeHost& host) {
    loop.watch(host.port_fd(), [&loop, &host] {
        host.on_readable();
        if (!host.link_gone().empty()) loop.unwatch(host.port_fd());
    });
    loop.watch(host.timer_fd(), [&host] { host.on_timer(); });
}

void watch_cycle(EventLoop& loop, Cycle& cycle, GcodeHost& host, hal::Camera& camera,
                 hal::Lines& lines) {
    watch_machine(loop, host);
    loop.watch(lines.button_fd(), [&cycle] { cycle.on_button(); });
    loop.watch(camera.completion_fd(), [&cycle] { cycle.on_camera(); });
    loop.watch(cycle.blink_fd(), [&cycle] { cycle.on_blink(); });
}

}  // namespace calbox::firmware
