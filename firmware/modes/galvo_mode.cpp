#include "firmware/modes/galvo_mode.hpp"

#include "core/jobs/job.hpp"
#include "core/modes/error_through.hpp"
#include "core/number_text.hpp"
#include "core/targets/galvo_target.hpp"
#include "firmware/cycle/overlays.hpp"
#include "firmware/cycle/photos.hpp"

namespace calbox::firmware {
namespace {

modes::ErrorFigures figures_of(const models::ErrorStatistics& s) {
    return {s.mean_mm, s.rms_mm, s.max_mm};
}

jobs::Correction through_table(const models::CorrectionTable& table) {
    return [table](geometry::Point2 p) { return table.command_for(p); };
}

}  // namespace

GalvoCycleMode::GalvoCycleMode(models::MachineFile machine, CycleSteps& steps)
    : KeptCorrectionMode(steps, {kGalvoTableFile, kNoGalvoTable, "backup-table.json",
                                 "keeping the table: jobs now go through it",
                                 "burning the grid again through the table"}),
      machine_(std::move(machine)) {}

void GalvoCycleMode::begin() {
    measured_.reset();
    solution_.reset();
}

void GalvoCycleMode::make_target(std::function<void(std::vector<std::string>)> then) {
    work_out<std::vector<std::string>>(
        steps_,
        [machine = machine_] {
            return lines_of(jobs::write_gcode(targets::make_galvo_target(machine).job, machine,
                                              "calbox target"));
        },
        std::move(then));
}

void GalvoCycleMode::measure(MeasureInput input, std::function<void()> then) {
    measure_photos(
        steps_, std::move(input),
        [this, machine = machine_](const CalibratedPhotos& photos, std::string& overlay) {
            // One photo of the whole grid: the first frame.
            auto measured =
                modes::measure_galvo(machine, photos.camera, photos.plane, photos.views.front());
            measured.photos = {photos.names.front()};
            overlay = galvo_overlay_png(photos.views.front(), measured, machine, photos.camera,
                                        photos.plane);
            return [this, measured] { measured_ = measured; };
        },
        std::move(then));
}

void GalvoCycleMode::solve(std::function<void(SolveOutcome)> then) {
    if (!steps_.keep(steps_.record_name("measurements.json"),
                     modes::galvo_measurements_to_json(*measured_)))
        return;
    steps_.enter(CycleState::solve, std::to_string(measured_->nodes.size()) + " marks, " +
                                        std::to_string(measured_->missing.size()) + " missing");
    auto solution = std::make_shared<modes::GalvoSolution>();
    auto field = std::make_shared<std::string>();
    auto in_force = std::make_shared<std::optional<modes::ErrorFigures>>();
    steps_.work(
        [machine = machine_, measured = *measured_, solution, field, in_force,
         kept = correction_in_force()] {
            *solution = modes::solve_galvo(machine, measured, std::nullopt);
            // Where each measured mark landed against the grid it was meant for.
            const auto& fit = solution->fit;
            std::vector<FieldArrow> arrows;
            std::vector<geometry::Point2> intended_mm, error_mm;
            for (std::size_t i = 0; i < fit.landed_mm.size() && i < solution->intended_mm.size();
                 ++i) {
                if (fit.filled[i]) continue;
                const auto& intended = solution->intended_mm[i];
                const geometry::Point2 error{fit.landed_mm[i].x - intended.x,
                                             fit.landed_mm[i].y - intended.y};
                arrows.push_back({intended, error});
                intended_mm.push_back(intended);
                error_mm.push_back(error);
            }
            *field = error_field_png(arrows, "galvo: each mark, landed - intended");
            if (kept) *in_force = modes::error_through(intended_mm, error_mm, *kept);
        },
        [this, solution, field, in_force, then = std::move(then)] {
            solution_ = *solution;
            if (!steps_.keep(steps_.record_name("error-field.png"), *field)) return;
            if (!steps_.keep(steps_.record_name("result.json"),
                             modes::galvo_result_to_json(*solution_)))
                return;
            if (!steps_.keep(steps_.record_name("table.csv"),
                             models::table_to_csv(solution_->fit.table)))
                return;
            const auto measured = figures_of(solution_->fit.before);
            then({SolveOutcome::Next::review, measured, in_force->value_or(measured)});
        });
}

ReviewText GalvoCycleMode::review() const {
    const auto& s = *solution_;
    const auto& t = s.fit.table;
    ReviewText r;
    r.detail = "predicted after " + number_text("%.4f", s.predicted_rms_mm) + " mm RMS";
    r.proposed = ("proposed: a " + std::to_string(t.nodes) + " x " + std::to_string(t.nodes) +
                  " table over X " + number_text("%.2f", t.min_x_mm) + ".." +
                  number_text("%.2f", t.max_x_mm) + " Y " + number_text("%.2f", t.min_y_mm) + ".." +
                  number_text("%.2f", t.max_y_mm) + " mm; error now " +
                  number_text("%.4f", s.fit.before.mean_mm) + " mm mean, " +
                  number_text("%.4f", s.fit.before.max_mm) + " mm worst; predicted after " +
                  number_text("%.4f", s.predicted_rms_mm) + " mm RMS");
    r.screen =
        ReviewScreen{{"a " + std::to_string(t.nodes) + "x" + std::to_string(t.nodes) + " table",
                      "mean error, in mm:"},
                     number_text("%.3f", s.fit.before.mean_mm),
                     number_text("%.3f", s.predicted_rms_mm)};
    return r;
}

void GalvoCycleMode::judge_verification(std::function<void(VerifyOutcome)> then) {
    auto again = std::make_shared<modes::GalvoSolution>();
    steps_.work([machine = machine_, measured = *measured_, through = solution_,
                 again] { *again = modes::solve_galvo(machine, measured, through); },
                [this, again, then = std::move(then)] {
                    if (!steps_.keep(steps_.record_name("verify-measurements.json"),
                                     modes::galvo_measurements_to_json(*measured_)))
                        return;
                    // Its "before" is the table's verified "after".
                    if (!steps_.keep(steps_.record_name("verify-result.json"),
                                     modes::galvo_result_to_json(*again)))
                        return;
                    const auto& v = again->fit.before;
                    steps_.log("verified on the grid burned through the table: " +
                               number_text("%.4f", v.mean_mm) + " mm mean, " +
                               number_text("%.4f", v.rms_mm) + " mm RMS, " +
                               number_text("%.4f", v.max_mm) + " mm worst");
                    then({figures_of(v), false});
                });
}

ModeResult GalvoCycleMode::result(bool applied) const {
    ModeResult r;
    if (!solution_ || !applied) return r;
    r.table = table_registers(solution_->fit.table);
    r.table_key = result_table().key;
    return r;
}

ModeTable GalvoCycleMode::result_table() {
    // The cycle's table (65 x 65 nodes): its node count and rectangle, then two floats a node,
    // two registers each.
    const int nodes = modes::GalvoSolveOptions{}.table_nodes;
    return {"galvo_table", "the galvo table", 2 * (5 + 2 * nodes * nodes), 1000};
}

std::vector<float> table_registers(const models::CorrectionTable& t) {
    std::vector<float> floats{static_cast<float>(t.nodes), static_cast<float>(t.min_x_mm),
                              static_cast<float>(t.min_y_mm), static_cast<float>(t.max_x_mm),
                              static_cast<float>(t.max_y_mm)};
    for (const auto& c : t.command_mm) {
        floats.push_back(static_cast<float>(c.x));
        floats.push_back(static_cast<float>(c.y));
    }
    return floats;
}

std::string GalvoCycleMode::kept_text() const {
    return modes::galvo_result_to_json(*solution_);
}

jobs::Correction GalvoCycleMode::correction() const {
    return through_table(solution_->fit.table);
}

jobs::Area GalvoCycleMode::measured_area() const {
    const auto& t = solution_->fit.table;
    return {t.min_x_mm, t.min_y_mm, t.max_x_mm, t.max_y_mm};
}

// A scanner's jobs are in its field's coordinates: the machine's own.
jobs::JobFrame GalvoCycleMode::target_frame() const {
    return {jobs::Flavour::grbl, {geometry::Point2{}}, {}, {}};
}

jobs::KeptCorrection GalvoCycleMode::correction_of(const std::string& kept_text) const {
    const auto table = modes::galvo_result_from_json(kept_text, kGalvoTableFile).fit.table;
    return {through_table(table), table.min_x_mm, table.min_y_mm, table.max_x_mm, table.max_y_mm};
}

std::string galvo_overlay_png(const vision::GrayView& photo,
                              const modes::GalvoMeasurement& measured,
                              const models::MachineFile& machine,
                              const geometry::CameraModel& camera,
                              const geometry::BedPlane& plane) {
    std::vector<GridMark> marks;
    for (const auto& n : measured.nodes)
        marks.push_back({n.measured_mm, n.index.column, n.index.row,
                         n.index.column % 5 == 0 && n.index.row % 5 == 0});
    return grid_overlay_png(photo, marks, measured.extra_mm, machine.galvo->substrate_height_mm,
                            camera, plane, {300, 1, 4000.0});
}

}  // namespace calbox::firmware
