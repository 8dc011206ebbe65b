#include "board/sim/sim_board.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <thread>

#include "board/sim/duet_twin.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/linuxcnc_twin.hpp"
#include "board/sim/moonraker_twin.hpp"
#include "board/sim/octoprint_twin.hpp"
#include "board/sim/photo_cache.hpp"
#include "board/sim/twin_kind.hpp"
#include "core/gcode/gcode_line.hpp"
#include "core/models/link_kinds.hpp"
#include "core/vision/image_codec.hpp"
#include "drivers/termios_port.hpp"

namespace calbox::sim {
namespace {

// A person holding the calibration board in front of the camera: tilted up to 30 degrees,
// turned, at distances where it fills about half to three quarters of the frame's width, the
// whole board in view. Seeded, so every run asks for the same views.
std::vector<Pose> calibration_poses(const CameraIntrinsics& camera,
                                    const geometry::PatternSpec& board, int count) {
    // The inner corners span columns-1 by rows-1 squares from the origin; the board is a square
    // wider on each side, its white margin reaches half a square beyond that.
    const double square = board.square_mm, margin = 1.5 * square;
    const double inner_w = (board.columns - 1) * square, inner_h = (board.rows - 1) * square;
    const double board_w = inner_w + 2 * square, board_h = inner_h + 2 * square;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> tilt(-30, 30), shift(-1, 1), fill(0.5, 0.75),
        spin(-20, 20);
    std::vector<Pose> poses;
    for (int attempt = 0; attempt < 10000 && static_cast<int>(poses.size()) < count; ++attempt) {
        Pose pose;
        pose.rotation =
            rotation_from_vector(Vec3{radians(tilt(rng)), radians(tilt(rng)), radians(spin(rng))});
        const Vec3 centre = pose.rotation * Vec3{inner_w / 2, inner_h / 2, 0};
        const double z = camera.fx * board_w / (fill(rng) * camera.width_px);
        const double free_x = 0.5 * camera.width_px / camera.fx * z - board_w / 2;
        const double free_y = 0.5 * camera.height_px / camera.fy * z - board_h / 2;
        pose.translation_mm =
            Vec3{shift(rng) * std::max(0.0, free_x), shift(rng) * std::max(0.0, free_y), z} -
            centre;
        bool inside = true;
        for (const auto& corner :
             {Vec3{-margin, -margin, 0}, Vec3{inner_w + margin, -margin, 0},
              Vec3{-margin, inner_h + margin, 0}, Vec3{inner_w + margin, inner_h + margin, 0}}) {
            const Vec2 px = project_point(camera, pose, corner);
            inside = inside && px.x > 5 && px.y > 5 && px.x < camera.width_px - 5 &&
                     px.y < camera.height_px - 5;
        }
        if (inside) poses.push_back(pose);
    }
    if (static_cast<int>(poses.size()) < count)
        throw ScenarioError("the calibration board does not fit this camera's view");
    return poses;
}

// One mark near each corner of the camera's view, 7 % of the view in from its edges, where
// a person would stick them: in view, and (for the scenarios here) clear of the work area.
std::vector<ReferenceMark> reference_marks_of(const Scenario& s, const Pose& bed_to_camera) {
    std::vector<ReferenceMark> marks;
    if (!s.setup.reference_marks) return marks;
    if (!s.setup.reference_marks_at_mm.empty()) {
        for (const auto& at : s.setup.reference_marks_at_mm)
            marks.push_back({static_cast<int>(marks.size()), at});
        return marks;
    }
    const auto& c = s.camera->intrinsics;
    const Vec3 centre = bed_to_camera.camera_centre_in_plane();
    const Mat3 camera_to_bed = bed_to_camera.rotation.transposed();
    for (const auto& [u, v] : {std::pair{0.07, 0.07}, {0.93, 0.07}, {0.07, 0.93}, {0.93, 0.93}}) {
        const Vec2 n = undistort_pixel(c, u * c.width_px, v * c.height_px);
        const Vec3 ray = camera_to_bed * Vec3{n.x, n.y, 1};
        const double t = -centre.z / ray.z;
        marks.push_back(
            {static_cast<int>(marks.size()), Vec2{centre.x + t * ray.x, centre.y + t * ray.y}});
    }
    return marks;
}

}  // namespace

TwinBench::TwinBench(Scenario scenario, std::filesystem::path settings_file)
    : scenario_(std::move(scenario)), settings_file_(std::move(settings_file)) {
    if (!scenario_.camera) throw ScenarioError(scenario_.path + ": the sim board needs a [camera]");
    machine_ = make_machine_twin(scenario_);
    if (!settings_file_.empty() && std::filesystem::exists(settings_file_)) {
        // The printer as the last run left it: what it stored, loaded at power-on.
        std::ifstream in(settings_file_);
        for (std::string text; std::getline(in, text);) {
            try {
                if (!machine_->settings_command(gcode::parse_line(text)))
                    throw gcode::SyntaxError("not a settings command");
            } catch (const std::exception& e) {
                throw ScenarioError(settings_file_.string() + ": '" + text + "': " + e.what());
            }
        }
        machine_->settings_command(gcode::parse_line("M500"));
    }
    runner_ = std::make_unique<GcodeRunner>(*machine_, tool_settings_of(scenario_));
    reference_marks_ = reference_marks_of(scenario_, bed_to_camera());
    // A mark under the plane's board would be hidden in the photo its view is taken from.
    const auto board = geometry::parse_pattern_spec(scenario_.setup.plane_pattern);
    const Vec2 at = scenario_.setup.plane_board_at_mm;
    const double sq = board.square_mm;
    for (const auto& m : reference_marks_) {
        const double half = reference_sticker_half_side_mm(scenario_.setup.reference_dictionary,
                                                           scenario_.setup.reference_mark_mm);
        if (m.centre_mm.x + half > at.x - 2 * sq &&
            m.centre_mm.x - half < at.x + (board.columns + 1) * sq &&
            m.centre_mm.y + half > at.y - (board.rows + 1) * sq &&
            m.centre_mm.y - half < at.y + 2 * sq)
            throw ScenarioError(scenario_.path + ": [setup] reference mark " +
                                std::to_string(m.id) + " lies under the plane's board");
        const auto& c = scenario_.camera->intrinsics;
        for (const double dx : {-half, half}) {
            for (const double dy : {-half, half}) {
                const Vec2 px = project_point(c, bed_to_camera(),
                                              Vec3{m.centre_mm.x + dx, m.centre_mm.y + dy, 0});
                if (px.x < 0 || px.y < 0 || px.x > c.width_px - 1 || px.y > c.height_px - 1)
                    throw ScenarioError(scenario_.path + ": [setup] reference mark " +
                                        std::to_string(m.id) +
                                        " is not wholly in the camera's view");
            }
        }
    }
}

Pose TwinBench::bed_to_camera() const {
    const auto& camera = *scenario_.camera;
    return compose(knock_, look_at_pose(camera.position_mm, camera.look_at_mm, camera.roll_deg));
}

void TwinBench::knock_camera(double turn_deg, const Vec3& shift_mm) {
    const std::lock_guard lock(mutex_);
    Pose knock;
    knock.rotation = rotation_from_vector(Vec3{radians(turn_deg), 0, 0});
    knock.translation_mm = shift_mm;
    knock_ = compose(knock, knock_);
}

void TwinBench::store_settings() const {
    const auto* delta = dynamic_cast<const DeltaTwin*>(machine_.get());
    if (settings_file_.empty() || delta == nullptr) return;
    // Written aside and renamed over, so that a run stopped half-way leaves the old file whole.
    const std::filesystem::path aside = settings_file_.string() + ".new";
    {
        std::ofstream out(aside, std::ios::trunc);
        for (const auto& command : delta->stored_settings_commands()) out << command << "\n";
        if (!out.flush()) throw std::runtime_error(aside.string() + ": cannot write");
    }
    std::filesystem::rename(aside, settings_file_);
}

std::vector<std::string> TwinBench::run_printer_line(std::string_view line) {
    const std::lock_guard lock(mutex_);
    const std::size_t replies_before = runner_->result().replies.size();
    runner_->run_line(line);
    if (!is_grbl_system_command(line) && gcode::parse_line(line).is('M', 500)) store_settings();
    // The settings commands' own "ok" is the link's business: the printer link adds one per line.
    const auto& replies = runner_->result().replies;
    std::vector<std::string> out;
    for (std::size_t i = replies_before; i < replies.size(); ++i)
        if (replies[i] != "ok") out.push_back(replies[i]);
    return out;
}

Vec3 TwinBench::machine_work_zero_mm() const {
    const std::lock_guard lock(mutex_);
    return machine_->work_zero_mm();
}

DeltaParams TwinBench::delta_printer_firmware() const {
    const std::lock_guard lock(mutex_);
    const auto* delta = dynamic_cast<const DeltaTwin*>(machine_.get());
    if (delta == nullptr) throw std::logic_error("the twin machine is not a delta printer");
    return delta->firmware();
}

void TwinBench::restart_delta_printer(const DeltaParams& firmware,
                                      double klipper_probe_z_offset_mm) {
    const std::lock_guard lock(mutex_);
    const auto* delta = dynamic_cast<const DeltaTwin*>(machine_.get());
    if (delta == nullptr) throw std::logic_error("the twin machine is not a delta printer");
    scenario_.delta_firmware = firmware;
    auto restarted = std::make_unique<DeltaTwin>(scenario_.delta_truth, firmware, delta->dialect());
    restarted->set_klipper_probe_z_offset(klipper_probe_z_offset_mm);
    replace_printer(std::move(restarted));
}

CartesianFirmware TwinBench::cartesian_printer_firmware() const {
    const std::lock_guard lock(mutex_);
    const auto* cartesian = dynamic_cast<const CartesianTwin*>(machine_.get());
    if (cartesian == nullptr) throw std::logic_error("the twin machine is not a cartesian printer");
    return cartesian->firmware();
}

void TwinBench::restart_cartesian_printer(const CartesianFirmware& firmware) {
    const std::lock_guard lock(mutex_);
    if (dynamic_cast<const CartesianTwin*>(machine_.get()) == nullptr)
        throw std::logic_error("the twin machine is not a cartesian printer");
    replace_printer(std::make_unique<CartesianTwin>(scenario_.cartesian_truth, firmware));
}

void TwinBench::set_cartesian_skew(double xy_skew) {
    const std::lock_guard lock(mutex_);
    auto* cartesian = dynamic_cast<CartesianTwin*>(machine_.get());
    if (cartesian == nullptr) throw std::logic_error("the twin machine is not a cartesian printer");
    cartesian->set_skew(xy_skew);
}

void TwinBench::change_machine(const std::function<void(Scenario&)>& change) {
    const std::lock_guard lock(mutex_);
    change(scenario_);
    remake_printer();
}

void TwinBench::reset_printer() {
    const std::lock_guard lock(mutex_);
    remake_printer();
}

// Under the mutex.
void TwinBench::remake_printer() {
    // The settings the firmware stored survive; what it held in RAM and its homing do not.
    if (auto* delta = dynamic_cast<DeltaTwin*>(machine_.get())) {
        replace_printer(std::make_unique<DeltaTwin>(scenario_.delta_truth, delta->stored_firmware(),
                                                    delta->dialect()));
    } else {
        replace_printer(make_machine_twin(scenario_));
    }
}

// Under the mutex: the material laid so far stays on the bed.
void TwinBench::replace_printer(std::unique_ptr<MachineTwin> machine) {
    const auto& strokes = runner_->result().strokes;
    for (std::size_t i = strokes_cleared_; i < strokes.size(); ++i)
        earlier_runs_.push_back(material_of(strokes[i]));
    machine_ = std::move(machine);
    runner_ = std::make_unique<GcodeRunner>(*machine_, tool_settings_of(scenario_));
    strokes_cleared_ = 0;
}

GrayImage TwinBench::photograph(std::uint64_t frame, const hal::CaptureRequest& asked) const {
    std::vector<StrokeSegment> strokes;
    std::optional<Board> board;
    {
        const std::lock_guard lock(mutex_);
        board = board_;
        strokes = earlier_runs_;
        const auto& laid = runner_->result().strokes;
        for (std::size_t i = strokes_cleared_; i < laid.size(); ++i)
            strokes.push_back(material_of(laid[i]));
    }
    const auto& camera = *scenario_.camera;
    // The lamp mirrored by what is in view: the board when one is, else the bed (the copy taken
    // under the mutex: the operator's hands move board_ while a capture renders).
    PhotoSettings photo = photo_settings_of(scenario_, board ? InView::board : InView::bed);
    photo.seed = scenario_.photo.seed + 7919 * frame;
    if (asked.exposure)
        photo.exposure_time_ratio =
            static_cast<double>(asked.exposure->count()) / scenario_.nominal_exposure_us;
    if (asked.analogue_gain) photo.analogue_gain = *asked.analogue_gain;
    const auto& setup = scenario_.setup;
    PhotoKey key;
    key.add(camera.intrinsics).add(photo).add(reference_marks_).add(setup.reference_dictionary);
    key.add(setup.reference_mark_mm);
    const auto with_marks = [&](const Scene& scene, const double to_bed[2][2], Vec2 origin) {
        return ReferenceMarksScene(scene, reference_marks_, setup.reference_dictionary,
                                   setup.reference_mark_mm, photo.supersample, to_bed, origin);
    };
    const auto kept_or_rendered = [&key](const auto& render) {
        if (auto kept = kept_photo(key)) return std::move(*kept);
        GrayImage image = render();
        keep_photo(key, image);
        return image;
    };
    if (board) {
        key.add(board->on_bed ? "board on the bed" : "board held").add(board->spec);
        key.add(board->board_to_camera).add(static_cast<std::int64_t>(setup.board_surroundings));
        const BoardScene scene(geometry::parse_pattern_spec(board->spec), photo.supersample,
                               setup.board_surroundings);
        if (!board->on_bed) {
            return kept_or_rendered([&] {
                return render_photo(camera.intrinsics, board->board_to_camera, scene, photo);
            });
        }
        // Face up on the bed: the board's y runs the other way from the bed's.
        key.add(setup.plane_board_at_mm);
        return kept_or_rendered([&] {
            const double to_bed[2][2] = {{1, 0}, {0, -1}};
            return render_photo(camera.intrinsics, board->board_to_camera,
                                with_marks(scene, to_bed, setup.plane_board_at_mm), photo);
        });
    }
    if (const auto& placing = scenario_.placement; placing && placing->on_bed_at_start)
        return placing->card ? photograph_card(*placing->card, placing->thickness_mm, photo)
                             : photograph_sheet(placing->sheet, placing->thickness_mm, photo);
    Pose bed_to_camera_now;
    {
        const std::lock_guard lock(mutex_);
        bed_to_camera_now = bed_to_camera();
    }
    auto photographed = as_photographed(scenario_, std::move(strokes));
    const double footprint_mm = stroke_footprint_mm(scenario_);
    key.add("the bed").add(photographed).add(scenario_.bed_albedo).add(scenario_.material_albedo);
    key.add(footprint_mm).add(scenario_.surface).add(bed_to_camera_now);
    return kept_or_rendered([&] {
        const StrokeScene scene(std::move(photographed), scenario_.bed_albedo,
                                scenario_.material_albedo, photo.supersample, footprint_mm,
                                scenario_.surface);
        const double identity[2][2] = {{1, 0}, {0, 1}};
        return render_photo(camera.intrinsics, bed_to_camera_now,
                            with_marks(scene, identity, {0, 0}), photo);
    });
}

GrayImage TwinBench::photograph_sheet(const StockSheet& sheet, double thickness_mm,
                                      const PhotoSettings& photo) const {
    Pose bed_to_camera_now;
    {
        const std::lock_guard lock(mutex_);
        bed_to_camera_now = bed_to_camera();
    }
    // The scene's plane is the sheet's top.
    Pose lifted;
    lifted.translation_mm = {0, 0, thickness_mm};
    return render_photo(scenario_.camera->intrinsics, compose(bed_to_camera_now, lifted),
                        SheetScene(sheet, photo.supersample), photo);
}

GrayImage TwinBench::photograph_card(const PrintedCard& card, double thickness_mm,
                                     const PhotoSettings& photo) const {
    Pose bed_to_camera_now;
    {
        const std::lock_guard lock(mutex_);
        bed_to_camera_now = bed_to_camera();
    }
    std::vector<StrokeSegment> ink;
    for (const Vec2& m : card.marks_mm) {
        const Vec2 c = card.on_bed(m);
        ink.push_back({{c.x, c.y, 0},
                       {c.x, c.y, 0},
                       card.mark_diameter_mm * std::sqrt(card.stretch_x * card.stretch_y)});
    }
    for (std::size_t k = 0; k + 1 < card.line_mm.size(); ++k) {
        const Vec2 a = card.on_bed(card.line_mm[k]), b = card.on_bed(card.line_mm[k + 1]);
        ink.push_back({{a.x, a.y, 0}, {b.x, b.y, 0}, 0.4});
    }
    Pose lifted;
    lifted.translation_mm = {0, 0, thickness_mm};
    const Pose card_to_camera = compose(bed_to_camera_now, lifted);
    return render_photo(
        scenario_.camera->intrinsics, card_to_camera,
        StrokeScene(std::move(ink), card.card_albedo, card.ink_albedo, photo.supersample,
                    stroke_footprint_mm(scenario_.camera->intrinsics,
                                        card_to_camera.translation_mm.norm())),
        photo);
}

void TwinBench::hold_calibration_board(int view) {
    if (view < 0 || view >= kCalibrationViews)
        throw std::out_of_range("calibration view " + std::to_string(view));
    const std::lock_guard lock(mutex_);
    // The same views every time: worked out once, on the first one asked for.
    if (calibration_poses_.empty())
        calibration_poses_ = calibration_poses(
            scenario_.camera->intrinsics,
            geometry::parse_pattern_spec(scenario_.setup.calibration_pattern), kCalibrationViews);
    board_ = Board{scenario_.setup.calibration_pattern,
                   calibration_poses_[static_cast<std::size_t>(view)], false};
}

void TwinBench::lay_plane_board_on_bed() {
    const std::lock_guard lock(mutex_);
    const Vec2 at = scenario_.setup.plane_board_at_mm;
    board_ = Board{scenario_.setup.plane_pattern,
                   compose(bed_to_camera(), board_lying_on_bed({at.x, at.y, 0}, 0)), true};
}

void TwinBench::take_board_away() {
    const std::lock_guard lock(mutex_);
    board_.reset();
}

void TwinBench::clear_bed() {
    const std::lock_guard lock(mutex_);
    runner_->forget_strokes();
    strokes_cleared_ = 0;
    earlier_runs_.clear();
}

GalvoJudgement TwinBench::judge_galvo_scanner(const std::function<Vec2(Vec2)>& command_for,
                                              const std::array<double, 4>& area_mm) const {
    {
        const std::lock_guard lock(mutex_);
        if (dynamic_cast<const GalvoTwin*>(machine_.get()) == nullptr)
            throw ScenarioError("the judge judges galvo scanners here");
    }
    const auto fresh = fresh_grid(area_mm, 30);
    return judge_galvo(scenario_.galvo_truth, fresh, command_for);
}

DeltaJudgement TwinBench::judge_delta_printer() const {
    const std::lock_guard lock(mutex_);
    const auto* delta = dynamic_cast<const DeltaTwin*>(machine_.get());
    if (delta == nullptr) throw ScenarioError("the judge judges delta printers");
    DeltaTwin copy = *delta;
    return judge_delta(copy, {}, scenario_.machine.bed_radius_mm);
}

RouterVerdict TwinBench::judge_cartesian_printer(const jobs::Correction* correct) const {
    const std::lock_guard lock(mutex_);
    const auto* cartesian = dynamic_cast<const CartesianTwin*>(machine_.get());
    if (cartesian == nullptr) throw ScenarioError("the judge judges cartesian printers here");
    return judge_cartesian_fresh_points(*cartesian, scenario_.machine, correct);
}

// What the machine's firmware says when it starts (its board resets as its port opens): Marlin's
// "start" and its version, grbl's welcome line. RepRapFirmware on native USB does not reset and
// says nothing until asked; the box then waits its start-up time and sends.
TwinCamera::TwinCamera(std::shared_ptr<TwinBench> bench) : bench_(std::move(bench)) {}

void TwinCamera::start_capture(const hal::CaptureRequest& request) {
    if (capture_.busy()) throw std::logic_error("a capture is already running");
    const int capture = ++captures_;
    const auto& faults = bench_->scenario().faults;
    const bool fail = faults.camera_fails_at_capture == capture;
    if (faults.camera_hangs_at_capture == capture)
        std::this_thread::sleep_for(std::chrono::duration<double>(faults.camera_hang_s));
    const std::uint64_t first_frame = frames_taken_;
    frames_taken_ += static_cast<std::uint64_t>(std::max(1, request.frame_count));
    capture_.start([this, request, fail, first_frame] {
        hal::CaptureResult result;
        try {
            for (int k = 0; k < std::max(1, request.frame_count); ++k) {
                if (fail && k == request.frame_count / 2) {
                    result.frames.clear();
                    result.error = "camera: frame " + std::to_string(k + 1) + " of " +
                                   std::to_string(request.frame_count) +
                                   " never arrived (sensor timeout)";
                    break;
                }
                const GrayImage image =
                    bench_->photograph(first_frame + static_cast<std::uint64_t>(k), request);
                hal::Frame frame;
                frame.width_px = image.width_px;
                frame.height_px = image.height_px;
                frame.stride_bytes = image.width_px;
                frame.pixels = image.pixels;
                frame.metadata.sequence = first_frame + static_cast<std::uint64_t>(k);
                frame.metadata.exposure = request.exposure.value_or(
                    std::chrono::microseconds(std::lround(bench_->scenario().nominal_exposure_us)));
                frame.metadata.analogue_gain = request.analogue_gain.value_or(1.0);
                result.frames.push_back(std::move(frame));
            }
        } catch (const std::exception& e) {
            result.frames.clear();
            result.error = std::string("camera: ") + e.what();
        }
        return result;
    });
}

hal::CaptureResult TwinCamera::take_frames() {
    auto result = capture_.take();
    if (!result) return hal::CaptureResult{{}, "camera: no capture has finished"};
    return std::move(*result);
}

SimLines::SimLines(hal::Clock& clock, Log log) : clock_(clock), log_(std::move(log)) {}

std::optional<hal::ButtonEvent> SimLines::read_button() {
    const std::lock_guard lock(mutex_);
    if (pending_.empty()) {
        edges_.take();
        return std::nullopt;
    }
    const auto event = pending_.front();
    pending_.erase(pending_.begin());
    if (pending_.empty()) edges_.take();
    return event;
}

void SimLines::press(std::chrono::milliseconds held) {
    const auto now = clock_.now();
    {
        const std::lock_guard lock(mutex_);
        pending_.push_back({true, now});
        pending_.push_back({false, now + held});
    }
    edges_.signal();
}

void SimLines::set_led(hal::Led which, bool on) {
    leds_[static_cast<std::size_t>(which)] = on;
}

void SimLines::set_light(bool on) {
    if (light_ == on) return;
    light_ = on;
    log_(std::string("light ") + (on ? "on" : "off"));
}

PngDisplay::PngDisplay(std::filesystem::path directory) : directory_(std::move(directory)) {
    std::filesystem::create_directories(directory_);
}

void PngDisplay::show(const hal::MonoBitmap& frame) {
    if (frame.width_px() != width_px() || frame.height_px() != height_px())
        throw std::invalid_argument("display: frame is not 128x64");
    std::vector<std::uint8_t> image(static_cast<std::size_t>(frame.width_px()) * frame.height_px());
    for (int y = 0; y < frame.height_px(); ++y)
        for (int x = 0; x < frame.width_px(); ++x)
            image[static_cast<std::size_t>(y) * frame.width_px() + x] = frame.at(x, y) ? 255 : 0;
    const auto png =
        vision::png_bytes({image.data(), frame.width_px(), frame.height_px(), frame.width_px(), 1});
    char name[32];
    std::snprintf(name, sizeof name, "%04d.png", ++frames_);
    const auto path = directory_ / name;
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
    out.close();
    if (!out) throw std::runtime_error(path.string() + ": cannot write the frame");
}

namespace {

// What a twin host is made from: the bench, its disk, the key file's text and the settings.
struct TwinHostContext {
    const std::string& scenario_path;
    std::shared_ptr<TwinBench> bench;
    std::filesystem::path dir;
    std::string key_text;
    TwinHostSettings settings;
    const models::MachineFile& machine() const { return bench->scenario().machine; }
};

std::unique_ptr<TwinHostServer> moonraker_twin(const TwinHostContext& c) {
    if (!c.machine().is_printer())
        throw ScenarioError(c.scenario_path +
                            ": the twin's Moonraker host serves a Klipper delta or cartesian "
                            "printer");
    return std::make_unique<MoonrakerTwin>(c.bench, c.dir, c.settings);
}
std::unique_ptr<TwinHostServer> octoprint_twin(const TwinHostContext& c) {
    return std::make_unique<OctoPrintTwin>(c.bench, c.dir, c.settings);
}
std::unique_ptr<TwinHostServer> duet_twin(const TwinHostContext& c) {
    return std::make_unique<DuetTwin>(c.bench, c.dir, c.settings);
}
std::unique_ptr<TwinHostServer> linuxcnc_twin(const TwinHostContext& c) {
    if (c.machine().kind != "router")
        throw ScenarioError(c.scenario_path +
                            ": the twin's LinuxCNC drives a router ([machine] kind = \"router\")");
    if (c.bench->scenario().host_tls)
        throw ScenarioError(c.scenario_path + ": linuxcncrsh speaks no TLS");
    return std::make_unique<LinuxCncTwin>(c.bench, c.key_text, c.settings.faults);
}

// One twin per kind of core/models/link_kinds.hpp: a host on loopback, or (serial, none here)
// the twin printer on a pty.
struct TwinHostFactory {
    std::string_view kind;
    std::unique_ptr<TwinHostServer> (*make)(const TwinHostContext&);
    int passwords = 1;  // the key file's words
};
constexpr std::array<TwinHostFactory, 5> kTwinHosts{{
    {"serial", nullptr},
    {"moonraker", moonraker_twin},
    {"octoprint", octoprint_twin},
    {"duet", duet_twin},
    {"linuxcnc", linuxcnc_twin, 2},  // the connect and the enable password
}};
static_assert(models::names_every_link_kind(kTwinHosts),
              "every kind of core/models/link_kinds.hpp needs its twin here, and only those");

const TwinHostFactory& twin_host_for(const std::string& kind) {
    for (const auto& t : kTwinHosts)
        if (t.kind == kind) return t;
    throw ScenarioError("[link] kind '" + kind + "' has no twin on the sim board");
}

// The host's key (or passwords), made anew each run and handed to the box in its key file (the
// scenario's own key_file, if any, is a real box's and not read).
std::string new_key_file(const std::filesystem::path& key_file, int words) {
    std::random_device random;
    std::string text;
    for (int w = 0; w < words; ++w) {
        char key[33];
        std::snprintf(key, sizeof key, "%08x%08x%08x%08x", random(), random(), random(), random());
        // Piece by piece: GCC 12 at -O3 warns falsely (-Wrestrict) on a literal + a temporary.
        if (w > 0) text += ' ';
        text.append(key, w == 0 ? 32 : 16);
    }
    {
        std::ofstream out(key_file, std::ios::trunc);
        out << text << "\n";
        if (!out.flush()) throw ScenarioError(key_file.string() + ": cannot write");
    }
    std::filesystem::permissions(
        key_file, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
    return text;
}

}  // namespace

SimBoard make_sim_board(const SimSettings& settings, hal::Clock& clock, const SimLines::Log& log) {
    SimBoard board;
    board.bench = std::make_shared<TwinBench>(load_scenario(settings.scenario_path),
                                              settings.data_dir / kTwinSettingsFile);
    const auto& machine = board.bench->scenario().machine;
    board.machine = machine;
    std::unique_ptr<hal::SerialPort> port;
    const TwinHostFactory& twin = twin_host_for(machine.link.kind);
    if (twin.make != nullptr) {
        const auto key_file = settings.data_dir / kTwinHostKeyFile;
        const std::string key_text = new_key_file(key_file, twin.passwords);
        const auto& scenario = board.bench->scenario();
        const TwinHostSettings host{key_text, scenario.faults.host, machine.bed_radius_mm,
                                    scenario.host_print_seconds, scenario.duet_sbc};
        board.host = twin.make({settings.scenario_path, board.bench,
                                settings.data_dir / kTwinHostDirectory, key_text, host});
        board.machine.link.url = board.host->url();
        board.machine.link.key_file = key_file.string();
        if (scenario.host_tls) {
            const auto certificate = drivers::self_signed_certificate({"127.0.0.1"}, 1);
            const auto ca_file = settings.data_dir / kTwinHostCertificateFile;
            write_file_whole(ca_file, certificate.certificate_pem);
            board.tls_front = std::make_unique<drivers::TlsTerminator>(
                "127.0.0.1", std::stoi(net::parse_url(board.host->url()).port), certificate);
            board.machine.link.url = "https://127.0.0.1:" + std::to_string(board.tls_front->port());
            board.machine.link.ca_file = ca_file.string();
        }
    } else {
        board.printer = std::make_unique<TwinPrinterLink>(board.bench);
        port = board::serial_port(board.printer->device_path(), settings.baud);
    }
    auto camera = std::make_unique<TwinCamera>(board.bench);
    auto lines = std::make_unique<SimLines>(clock, log);
    auto display = std::make_unique<PngDisplay>(settings.data_dir / "display");
    board.camera = camera.get();
    board.lines = lines.get();
    board.display = display.get();
    board.devices = {std::move(camera), std::move(lines), std::move(display), std::move(port),
                     board::network()};
    return board;
}

}  // namespace calbox::sim
