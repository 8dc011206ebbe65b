#include "firmware/modes/planar_mode.hpp"

#include <algorithm>
#include <cmath>

#include "core/modes/bed_view.hpp"
#include "core/modes/error_through.hpp"
#include "core/number_text.hpp"
#include "core/targets/planar_target.hpp"
#include "firmware/cycle/overlays.hpp"
#include "firmware/cycle/photos.hpp"

namespace calbox::firmware {
namespace {

// The error norms' figures: the model's statistics have a mean and a worst, the RMS from the
// errors themselves.
modes::ErrorFigures figures_of(const modes::PlanarSolution& s) {
    double sum = 0;
    for (const auto& e : s.error_mm) sum += e.x * e.x + e.y * e.y;
    const double rms =
        std::sqrt(sum / static_cast<double>(std::max<std::size_t>(1, s.error_mm.size())));
    return {s.before.mean_mm, rms, s.before.max_mm};
}

jobs::Correction through_model(const modes::PlanarSolution& solution) {
    return [solution](geometry::Point2 p) { return modes::planar_command_for(solution, p); };
}

}  // namespace

PlanarCycleMode::PlanarCycleMode(models::MachineFile machine, CycleSteps& steps)
    : KeptCorrectionMode(
          steps, {kPlanarResultFile, kNoPlanarResult, "backup-result.json",
                  "keeping the error model: jobs now go through it",
                  machine.is_printer() ? "printing the grid again through the error model"
                                       : "drilling the grid again through the error model"}),
      machine_(std::move(machine)) {}

void PlanarCycleMode::begin() {
    measured_.reset();
    solution_.reset();
    firmware_.reset();
    klipper_now_.reset();
    klipper_sent_.reset();
}

void PlanarCycleMode::make_target(std::function<void(std::vector<std::string>)> then) {
    work_out<std::vector<std::string>>(
        steps_, [machine = machine_] { return lines_of(targets::make_planar_target(machine).job); },
        std::move(then));
}

void PlanarCycleMode::measure(MeasureInput input, std::function<void()> then) {
    measure_photos(
        steps_, std::move(input),
        [this, machine = machine_](const CalibratedPhotos& photos, std::string& overlay) {
            // The box's camera sees the whole sheet: the first frame.
            auto measured =
                modes::measure_planar(machine, photos.camera, photos.plane, photos.views.front());
            measured.photos = {photos.names.front()};
            overlay = planar_overlay_png(photos.views.front(), measured, machine, photos.camera,
                                         photos.plane);
            auto kept = std::make_shared<BedPhoto>(
                bed_photo_of(photos.views.front(), photos.camera, photos.plane));
            return [this, measured, kept] {
                measured_ = measured;
                bed_photo_ = kept;
            };
        },
        std::move(then));
}

void PlanarCycleMode::solve(std::function<void(SolveOutcome)> then) {
    if (!steps_.keep(steps_.record_name("measurements.json"),
                     modes::planar_measurements_to_json(*measured_)))
        return;
    steps_.enter(CycleState::solve, std::to_string(measured_->holes.size()) + " holes, " +
                                        std::to_string(measured_->missing.size()) + " missing");
    auto solution = std::make_shared<modes::PlanarSolution>();
    auto firmware = std::make_shared<modes::FirmwareSettings>();
    auto field = std::make_shared<std::string>();
    auto in_force = std::make_shared<std::optional<modes::ErrorFigures>>();
    auto bed_view = std::make_shared<std::optional<std::pair<std::string, std::string>>>();
    auto bed_view_refused = std::make_shared<std::string>();
    steps_.work(
        [machine = machine_, measured = *measured_, solution, firmware, field, in_force,
         zero = controller_work_zero_, kept = correction_in_force(), bed_photo = bed_photo_,
         bed_view, bed_view_refused] {
            *solution = modes::solve_planar(machine, measured);
            if (zero && solution->frame) {
                solution->frame->work_zero_mm = *zero;
                solution->frame->work_zero_from = "the controller's G54 ($#)";
            }
            *firmware = modes::planar_firmware_settings(machine, *solution);
            std::vector<FieldArrow> arrows;
            arrows.reserve(solution->error_mm.size());
            for (std::size_t i = 0; i < solution->error_mm.size(); ++i)
                arrows.push_back({solution->commanded_mm[i], solution->error_mm[i]});
            *field = error_field_png(arrows, "planar: each hole's error, seen - commanded");
            if (kept)
                *in_force = modes::error_through(solution->commanded_mm, solution->error_mm, *kept,
                                                 [s = *solution](geometry::Point2 p) {
                                                     return models::planar_error_mm(
                                                         s.fit.parameters, p, s.tool_length_mm);
                                                 });
            if (bed_photo)
                *bed_view = bed_view_files(*bed_photo, *solution, machine.planar->surface_height_mm,
                                           *bed_view_refused);
        },
        [this, solution, firmware, field, in_force, bed_view, bed_view_refused,
         then = std::move(then)] {
            solution_ = *solution;
            firmware_ = *firmware;
            if (klipper_now_)
                klipper_sent_ = models::klipper_cartesian_corrected(
                    *klipper_now_, firmware->scale_x, firmware->scale_y, firmware->skew);
            if (!steps_.keep(steps_.record_name("result.json"),
                             modes::planar_result_to_json(*solution_, *firmware)))
                return;
            // The firmware's own knobs, for a person who would rather set them: shown, not sent
            // (the compensated jobs carry the whole model; both would correct twice). Klipper
            // behind its host takes the review's instead.
            if (!steps_.keep(steps_.record_name("firmware.txt"), joined(firmware->lines))) return;
            if (!steps_.keep(steps_.record_name("error-field.png"), *field)) return;
            if (*bed_view) {
                if (!steps_.keep(steps_.record_name("bed-view.png"), (*bed_view)->first) ||
                    !steps_.keep(steps_.record_name("bed-view.pgw"), (*bed_view)->second))
                    return;
            } else if (!bed_view_refused->empty()) {
                steps_.log("no bed view: " + *bed_view_refused, hal::LogLevel::warning);
            }
            const auto measured = figures_of(*solution_);
            then({SolveOutcome::Next::review, measured, in_force->value_or(measured)});
        });
}

ReviewText PlanarCycleMode::review() const {
    if (klipper_sent_) return klipper_review();
    const auto& s = *solution_;
    ReviewText r;
    r.detail = "predicted after " + number_text("%.4f", s.after.mean_mm) + " mm mean";
    r.proposed = ("proposed: the error model over X " + number_text("%.1f", s.min_x_mm) + ".." +
                  number_text("%.1f", s.max_x_mm) + " Y " + number_text("%.1f", s.min_y_mm) + ".." +
                  number_text("%.1f", s.max_y_mm) + " mm; error norm now " +
                  number_text("%.4f", s.before.mean_mm) + " mm mean, " +
                  number_text("%.4f", s.before.max_mm) + " mm worst; predicted after " +
                  number_text("%.4f", s.after.mean_mm) + " mm mean, " +
                  number_text("%.4f", s.after.max_mm) + " mm worst");
    r.screen = ReviewScreen{
        {"error model, " + std::to_string(s.fit.rank - 3) + " terms", "mean error, in mm:"},
        number_text("%.3f", s.before.mean_mm),
        number_text("%.3f", s.after.mean_mm)};
    return r;
}

void PlanarCycleMode::judge_verification(std::function<void(VerifyOutcome)> then) {
    auto again = std::make_shared<modes::PlanarSolution>();
    steps_.work([machine = machine_, measured = *measured_,
                 again] { *again = modes::solve_planar(machine, measured); },
                [this, again, then = std::move(then)] {
                    // The holes drilled through the model against where they were meant: the second
                    // solve's "before".
                    const auto verified = figures_of(*again);
                    if (!steps_.keep(steps_.record_name("verify-measurements.json"),
                                     modes::planar_measurements_to_json(*measured_)))
                        return;
                    steps_.log(std::string(klipper_sent_ ? "verified on the grid made again: "
                                                         : "verified on the grid drilled through "
                                                           "the model: ") +
                               number_text("%.4f", *verified.mean_mm) + " mm mean, " +
                               number_text("%.4f", verified.max_mm) + " mm worst");
                    then({verified, false});
                });
}

std::string PlanarCycleMode::kept_text() const {
    return modes::planar_result_to_json(*solution_,
                                        modes::planar_firmware_settings(machine_, *solution_));
}

jobs::Correction PlanarCycleMode::correction() const {
    return through_model(*solution_);
}

jobs::Area PlanarCycleMode::measured_area() const {
    const auto& s = *solution_;
    return {s.min_x_mm, s.min_y_mm, s.max_x_mm, s.max_y_mm};
}

// The verification job is the target again, in the frame the target ran in: its work frame is
// the measured one, so the correction is taken in that frame as it is.
jobs::JobFrame PlanarCycleMode::target_frame() const {
    return {jobs::flavour_of_firmware(machine_.firmware), {geometry::Point2{}}, {}, {}};
}

jobs::KeptCorrection PlanarCycleMode::correction_of(const std::string& kept_text) const {
    const auto s = modes::planar_result_from_json(kept_text, kPlanarResultFile);
    return {through_model(s), s.min_x_mm, s.min_y_mm, s.max_x_mm, s.max_y_mm};
}

BedPhoto bed_photo_of(const vision::GrayView& view, const geometry::CameraModel& camera,
                      const geometry::BedPlane& plane) {
    BedPhoto kept{{}, camera, plane};
    kept.photo.width_px = view.width_px;
    kept.photo.height_px = view.height_px;
    kept.photo.pixels.reserve(static_cast<std::size_t>(view.width_px) * view.height_px);
    for (int y = 0; y < view.height_px; ++y) {
        const auto* row = view.pixels + static_cast<std::ptrdiff_t>(y) * view.stride_bytes;
        kept.photo.pixels.insert(kept.photo.pixels.end(), row, row + view.width_px);
    }
    return kept;
}

std::optional<std::pair<std::string, std::string>> bed_view_files(
    const BedPhoto& bed, const modes::PlanarSolution& solution, double surface_height_mm,
    std::string& refused, const modes::StockOutline* stock) {
    // The whole travel about 800 pixels across: enough to see the sheet and the frame, a
    // fraction of the photo's pixels to write.
    modes::BedViewRequest request;
    request.surface_height_mm = surface_height_mm;
    // One sample a pixel: a quarter of the work, and the bed and the sheet show alike.
    request.average_samples = false;
    if (solution.frame) {
        const auto& f = *solution.frame;
        const double extent =
            std::max(f.travel_max_x_mm - f.travel_min_x_mm, f.travel_max_y_mm - f.travel_min_y_mm);
        request.mm_per_px = std::ceil(extent / 800 * 20) / 20;
    }
    try {
        const auto view = modes::render_bed_view(bed.camera, bed.plane, bed.photo.view(), solution,
                                                 request, "the cycle's result");
        const auto colour = stock ? modes::bed_view_with_stock(view, solution, *stock)
                                  : modes::bed_view_with_overlay(view, solution);
        const auto png = vision::png_bytes({colour.data(), view.pixels.width_px,
                                            view.pixels.height_px, view.pixels.width_px * 3, 3});
        return std::pair{std::string(png.begin(), png.end()), modes::world_file_text(view)};
    } catch (const modes::BedViewError& e) {
        refused = e.what();
        return std::nullopt;
    }
}

std::string planar_overlay_png(const vision::GrayView& photo,
                               const modes::PlanarMeasurement& measured,
                               const models::MachineFile& machine,
                               const geometry::CameraModel& camera,
                               const geometry::BedPlane& plane) {
    // The holes are in the machine's frame (y flipped back for a mirrored photo); the picture
    // wants the photo's, in which the extra blobs already are.
    const double flip = measured.mirrored ? -1 : 1;
    std::vector<GridMark> marks;
    for (const auto& h : measured.holes)
        marks.push_back(
            {{h.measured_mm.x, flip * h.measured_mm.y}, h.index.column, h.index.row, h.large});
    return grid_overlay_png(photo, marks, measured.extra_mm, machine.planar->surface_height_mm,
                            camera, plane, {250, 2, 2000.0});
}

}  // namespace calbox::firmware
