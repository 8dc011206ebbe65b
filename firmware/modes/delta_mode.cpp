#include "firmware/modes/delta_mode.hpp"

#include <algorithm>
#include <limits>
#include <nlohmann/json.hpp>

#include "core/jobs/job.hpp"
#include "core/models/delta_commands.hpp"
#include "core/models/klipper_config.hpp"
#include "core/models/machine_import.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/number_text.hpp"
#include "core/targets/delta_target.hpp"
#include "firmware/cycle/overlays.hpp"
#include "firmware/cycle/photos.hpp"
#include "firmware/modes/klipper_host.hpp"

namespace calbox::firmware {
namespace {

// "M665 M666": commands named in a message.
std::string spaced(const std::vector<std::string>& words) {
    std::string out;
    for (const auto& w : words) out += (out.empty() ? "" : " ") + w;
    return out;
}

modes::ErrorFigures placement_figures(const modes::DeltaMeasurementsRecord& measured) {
    const auto errors = modes::placement_errors(measured.features);
    return {std::nullopt, errors.rms_mm, errors.largest_mm};
}

// A pass's files: the first pass's plain, a later one's "pass-N-".
std::string prefix_of_pass(std::size_t pass) {
    return pass == 1 ? std::string() : "pass-" + std::to_string(pass) + "-";
}

// The delta geometry a printer.cfg (or Klipper's settings in force, written as one) gives.
models::DeltaGeometry klipper_geometry(const std::string& text, const std::string& source) {
    const auto config = models::read_klipper_config(
        source, text, [](const std::string&) { return std::optional<std::string>(); });
    return models::from_klipper(config.delta);
}

}  // namespace

DeltaCycleMode::DeltaCycleMode(models::MachineFile machine, CycleSteps& steps,
                               modes::DeltaSolveOptions solve, modes::DeltaPassLimits passes)
    : machine_(std::move(machine)),
      steps_(steps),
      solve_options_(std::move(solve)),
      pass_limits_(passes) {}

void DeltaCycleMode::begin() {
    probe_.clear();
    measurements_.reset();
    passes_.clear();
    solution_.reset();
    backup_.clear();
}

void DeltaCycleMode::make_target(std::function<void(std::vector<std::string>)> then) {
    work_out<std::vector<std::string>>(
        steps_,
        [machine = machine_] {
            return lines_of(jobs::write_gcode(targets::make_delta_target(machine).job, machine,
                                              "calbox target"));
        },
        std::move(then));
}

void DeltaCycleMode::before_target(std::function<void()> then) {
    read_printer_settings([this, then = std::move(then)] { probe_printer(then); });
}

// The correction is worked out from the settings in force, which an earlier cycle, a revert or
// the owner may have changed since the machine file was written: they are read from the printer.
// Klipper's live in printer.cfg: read through its host (configfile.settings), else out of the
// link's reach, and the machine file's stand.
void DeltaCycleMode::read_printer_settings(std::function<void()> then) {
    if (machine_.firmware == "klipper") {
        if (!steps_.klipper_on_host(machine_)) {
            then();
            return;
        }
        read_klipper_settings([this, then = std::move(then)](const models::DeltaGeometry& g) {
            machine_.delta = g;
            steps_.log("the printer's settings in force: " + spaced(models::klipper_snippet(g)));
            then();
        });
        return;
    }
    read_settings([this, then = std::move(then)](const std::vector<std::string>& commands) {
        try {
            machine_.delta = models::geometry_from_settings(machine_.firmware, commands);
        } catch (const std::exception& e) {
            steps_.fail("the printer's reply to " +
                        spaced(models::settings_query(machine_.firmware)) + ": " + e.what());
            return;
        }
        steps_.log("the printer's settings: " + spaced(commands));
        then();
    });
}

// A printer with [probe]: its probe measures the gap on the clear bed, before the target is
// printed, into the record as probe.csv.
void DeltaCycleMode::probe_printer(std::function<void()> then) {
    probe_.clear();
    if (!machine_.probe) {
        then();
        return;
    }
    const auto points = modes::probe_points(*machine_.probe);
    steps_.enter(CycleState::wait_machine,
                 "the printer probes the bed: " + std::to_string(points.size()) + " points");
    steps_.send_commands(
        modes::probe_job(machine_.firmware, points),
        [this, points, then = std::move(then)](const JobOutcome& outcome) {
            try {
                probe_ = modes::probe_from_replies(machine_.firmware, points, outcome.replies,
                                                   machine_.probe->repeatability_mm,
                                                   klipper_probe_z_offset_mm_);
            } catch (const std::invalid_argument& e) {
                steps_.fail(std::string("the printer's probe report: ") + e.what());
                return;
            }
            double low = std::numeric_limits<double>::max();
            double high = std::numeric_limits<double>::lowest();
            for (const auto& p : probe_) {
                low = std::min(low, p.z_mm);
                high = std::max(high, p.z_mm);
            }
            if (!steps_.keep(steps_.record_name("probe.csv"), modes::probe_to_csv(probe_))) return;
            steps_.log("the printer's probe: " + std::to_string(probe_.size()) +
                       " points, the nozzle's gap ranging " + number_text("%.3f", high - low) +
                       " mm over the bed");
            then();
        });
}

void DeltaCycleMode::read_settings(std::function<void(std::vector<std::string>)> then) {
    steps_.send_commands(
        models::settings_query(machine_.firmware),
        [firmware = machine_.firmware, then = std::move(then)](const JobOutcome& o) {
            then(models::settings_from_report(firmware, o.replies));
        });
}

void DeltaCycleMode::send_and_read_back(
    const std::vector<std::string>& lines,
    std::function<void(std::string, std::vector<std::string>)> then,
    std::function<void(const std::string&)> failed) {
    const bool failure_is_error = !failed;
    steps_.ask_machine(
        [lines](MachineLink& m, MachineLink::Done done) {
            m.send_commands(lines, std::move(done));
        },
        [this, lines, then = std::move(then), failed = std::move(failed)](const JobOutcome& sent) {
            if (!sent.ok) {
                failed(sent.error);
                return;
            }
            read_settings(
                [firmware = machine_.firmware, lines, then](std::vector<std::string> reported) {
                    // Compared before the report is moved on (argument order is unspecified).
                    std::string mismatch = models::settings_mismatch(firmware, lines, reported);
                    then(std::move(mismatch), std::move(reported));
                });
        },
        failure_is_error);
}

void DeltaCycleMode::measure(MeasureInput input, std::function<void()> then) {
    measure_photos(
        steps_, std::move(input),
        [this, machine = machine_](const CalibratedPhotos& photos, std::string& overlay) {
            const auto measured =
                modes::measure_delta(machine, photos.camera, photos.plane, photos.views);
            overlay =
                delta_overlay_png(photos.views.front(), measured, photos.camera, photos.plane);
            // The placement errors on the machine's map: where each corner was commanded.
            const auto placed = modes::placement_errors(measured.features);
            std::vector<FieldArrow> arrows;
            arrows.reserve(placed.error_mm.size());
            for (std::size_t i = 0; i < placed.error_mm.size(); ++i)
                arrows.push_back(
                    {{measured.features[i].commanded_mm.x, measured.features[i].commanded_mm.y},
                     placed.error_mm[i]});
            std::string field = error_field_png(arrows, "delta: each corner's placement error");
            return [this, record = modes::record_of(measured, machine, photos.names),
                    field = std::move(field)] {
                measurements_ = record;
                // Named by the pass it opens, as that pass's result is: the first measurement's
                // plain, the one after n corrections pass-(n+1)'s.
                (void)steps_.keep(
                    steps_.record_name(prefix_of_pass(passes_.size() + 1) + "error-field.png"),
                    field);
            };
        },
        std::move(then));
}

void DeltaCycleMode::solve(std::function<void(SolveOutcome)> then) {
    // A later pass measures the verification print, kept as the pass before's.
    const int pass = static_cast<int>(passes_.size()) + 1;
    if (pass == 1 && !steps_.keep(steps_.record_name("measurements.json"),
                                  modes::measurements_to_json(*measurements_)))
        return;
    const auto from_fit =
        std::count_if(measurements_->features.begin(), measurements_->features.end(),
                      [](const auto& f) { return !f.height_measured; });
    steps_.enter(
        CycleState::solve,
        (pass > 1 ? "pass " + std::to_string(pass) + ": " : std::string()) +
            std::to_string(measurements_->features.size()) + " corners" +
            (from_fit > 0
                 ? ", " + std::to_string(from_fit) + " of their heights from the fit" +
                       (measurements_->heights_unmeasured.empty()
                            ? std::string()
                            : " (the first: " + measurements_->heights_unmeasured.front() + ")")
                 : std::string()));
    auto solution = std::make_shared<modes::DeltaSolution>();
    // The probe measured the printer as the first pass found it.
    auto probe = pass == 1 ? probe_ : std::vector<solve::ProbePoint>{};
    steps_.work(
        [machine = machine_, measurements = *measurements_, options = solve_options_, solution,
         probe = std::move(probe)] {
            *solution = modes::solve_delta(machine, measurements, probe, options);
        },
        [this, solution, pass, then = std::move(then)] {
            DeltaPassReport p;
            p.pass = pass;
            // What the pass measured was placed already: the cycle's first print, or the
            // verification print of the pass before.
            const modes::ErrorFigures measured =
                pass == 1
                    ? placement_figures(*measurements_)
                    : modes::ErrorFigures{std::nullopt, passes_.back().verify_xy_rms_mm.value(),
                                          passes_.back().verify_xy_max_mm.value()};
            p.measured_xy_rms_mm = measured.rms_mm;
            p.measured_xy_max_mm = measured.max_mm;
            const auto& c = solution->fit.correction;
            p.gap_range_mm = c.predicted_height_range_now_mm;
            p.xy_change_mm = c.predicted_xy_change_mm;
            p.height_change_mm = c.predicted_height_change_mm;
            p.step = modes::next_delta_pass_step(*solution, pass, pass_limits_);
            passes_.push_back(p);
            if (!steps_.keep(pass_file("result.json"), modes::result_to_json(*solution))) return;
            steps_.log(modes::describe_delta_pass(*solution, pass, p.step, pass_limits_));
            // A printer that holds keeps the correction in force: the one sent stays the report's.
            if (p.step == modes::DeltaPassStep::holds) {
                then({SolveOutcome::Next::done, measured, measured});
                return;
            }
            solution_ = *solution;
            // The owner reviewed the cycle's correction at its first pass; a later one is the
            // same calibration carried on (within the same bounds), applied as it comes so that
            // a button or a PLC confirms a cycle once.
            if (pass > 1) {
                for (const auto& command : solution_->commands) steps_.log_detail("  " + command);
                then({SolveOutcome::Next::apply, measured, measured});
                return;
            }
            then({SolveOutcome::Next::review, measured, measured});
        });
}

std::string DeltaCycleMode::pass_prefix() const {
    return prefix_of_pass(std::max<std::size_t>(passes_.size(), 1));
}

std::string DeltaCycleMode::pass_file(const std::string& what) const {
    return steps_.record_name(pass_prefix() + what);
}

ReviewText DeltaCycleMode::review() const {
    const auto& s = *solution_;
    const auto& before = s.fit.fitted.before;
    const auto& c = s.fit.correction;
    const auto& pass = passes_.back();
    ReviewText r;
    r.detail = "predicted XY after " + number_text("%.4f", c.predicted_xy_rms_mm) +
               " mm RMS (the fit's own uncertainty)";
    r.proposed =
        ("proposed: rod " + number_text("%.3f", before.diagonal_rod_mm) + " -> " +
         number_text("%.3f", s.after.diagonal_rod_mm) + " mm, radius " +
         number_text("%.3f", before.radius_mm) + " -> " + number_text("%.3f", s.after.radius_mm) +
         " mm; fit RMS " + number_text("%.4f", s.fit.fitted.fit_rms_mm) + " mm; predicted XY " +
         number_text("%.4f", c.predicted_xy_rms_mm) + " mm RMS, " +
         number_text("%.4f", c.predicted_xy_max_mm) +
         " mm worst (one standard uncertainty of the fit, carried through the correction)");
    for (const auto& command : s.commands) r.details.push_back("  " + command);
    r.screen = ReviewScreen{
        {"rod " + number_text("%+.3f", s.after.diagonal_rod_mm - before.diagonal_rod_mm) + " mm",
         "radius " + number_text("%+.3f", s.after.radius_mm - before.radius_mm) + " mm"},
        "XY " + number_text("%.3f", pass.measured_xy_rms_mm),
        number_text("%.3f", c.predicted_xy_rms_mm) + " mm"};
    return r;
}

void DeltaCycleMode::read_klipper_settings(std::function<void(models::DeltaGeometry)> then) {
    steps_.read_settings_in_force<models::DeltaGeometry>(
        [this](const std::string& text) {
            auto g = klipper_geometry(text, "Klipper's settings in force");
            klipper_probe_z_offset_mm_ =
                models::klipper_probe_z_offset("Klipper's settings in force", text);
            return g;
        },
        std::move(then));
}

// Klipper takes printer.cfg as a whole: the fitted values go where SAVE_CONFIG keeps them, the
// file as it was is the backup, and the settings Klipper took after its restart are compared.
void DeltaCycleMode::apply_on_klipper_host(std::function<void(bool verify)> then) {
    write_printer_cfg(
        steps_,
        {[this](const std::string& read) {
             return models::klipper_saved_config(read, solution_->after);
         },
         pass_file(kKlipperBackup), pass_file("printer.cfg"),
         "writing printer.cfg's SAVE_CONFIG block and restarting Klipper",
         [this, then = std::move(then)](const std::string& old, const std::string& updated) {
             read_klipper_settings([this, then, updated,
                                    old](const models::DeltaGeometry& in_force) {
                 const std::string mismatch =
                     models::klipper_settings_mismatch(solution_->after, in_force);
                 if (!mismatch.empty()) {
                     restore_klipper_config(old, updated, "apply: read-back mismatch: " + mismatch);
                     return;
                 }
                 machine_.delta = in_force;
                 then(true);
             });
         },
         [this](const std::string& old, const std::string& updated, const std::string& why) {
             restore_klipper_config(old, updated, why);
         }});
}

void DeltaCycleMode::restore_klipper_config(const std::string& backup, const std::string& written,
                                            const std::string& why) {
    restore_printer_cfg(
        steps_, backup, [written](const std::string& now) { return now == written; }, why);
}

void DeltaCycleMode::apply(std::function<void(bool verify)> then) {
    const auto& s = *solution_;
    if (steps_.klipper_on_host(machine_)) {
        apply_on_klipper_host(std::move(then));
        return;
    }
    if (s.firmware == "klipper") {
        // Klipper's geometry lives in printer.cfg: shown and stored, never pretended applied.
        if (!steps_.keep(steps_.record_name("printer.cfg"), joined(s.commands))) return;
        steps_.enter(CycleState::apply,
                     "Klipper: edit printer.cfg as " + steps_.record_name("printer.cfg") + " says");
        then(false);
        return;
    }
    steps_.enter(CycleState::apply,
                 "backing up the settings (" + spaced(models::settings_query(s.firmware)) + ")");
    read_settings([this, then = std::move(then)](std::vector<std::string> backup) {
        backup_ = std::move(backup);
        if (backup_.size() != 2) {
            steps_.fail("apply: the printer's reply to " +
                        spaced(models::settings_query(solution_->firmware)) +
                        " does not hold both its M665 and M666 settings to back up");
            return;
        }
        // Each pass backs up what it changes; revert goes back to before the cycle (pass 1's).
        if (!steps_.keep(pass_file("backup.gcode"), joined(backup_) + "M500\n")) return;
        steps_.log("sending " + std::to_string(solution_->commands.size()) + " lines");
        // A batch cut off part way may have set some of its lines: what was there goes back.
        send_and_read_back(
            solution_->commands,
            [this, then](const std::string& mismatch, const std::vector<std::string>&) {
                if (mismatch.empty()) {
                    machine_.delta = solution_->after;
                    then(true);
                    return;
                }
                restore_backup("apply: read-back mismatch: " + mismatch);
            },
            [this](const std::string& error) { restore_backup("apply: " + error); });
    });
}

// Puts back what was there, then stops with the reason.
void DeltaCycleMode::restore_backup(const std::string& why) {
    auto restore = backup_;
    restore.emplace_back("M500");
    steps_.log(why + "; restoring the backup", hal::LogLevel::warning);
    steps_.ask_machine(
        [restore](MachineLink& m, MachineLink::Done done) {
            m.send_commands(restore, std::move(done));
        },
        [this, why](const JobOutcome& restored) {
            steps_.fail(restored.ok ? why + " (the previous settings were restored)"
                                    : why + "; restoring the previous settings failed too: " +
                                          restored.error);
        },
        false);
}

void DeltaCycleMode::judge_verification(std::function<void(VerifyOutcome)> then) {
    const auto verified = placement_figures(*measurements_);
    if (!steps_.keep(pass_file("verify-measurements.json"),
                     modes::measurements_to_json(*measurements_)))
        return;
    steps_.log("verified on the re-printed target: XY " + number_text("%.4f", verified.rms_mm) +
               " mm RMS, " + number_text("%.4f", verified.max_mm) + " mm worst");
    auto& pass = passes_.back();
    pass.verify_xy_rms_mm = verified.rms_mm;
    pass.verify_xy_max_mm = verified.max_mm;
    // The verification print, on the levelled bed, is the next pass.
    if (pass.step == modes::DeltaPassStep::apply_then_measure_again) {
        then({verified, true});
        return;
    }
    if (pass.step == modes::DeltaPassStep::apply_and_stop_out_of_passes)
        steps_.notice("pass " + std::to_string(pass.pass) +
                      ", the last allowed, still corrected the printer by up to " +
                      number_text("%.3f", std::max(pass.xy_change_mm, pass.height_change_mm)) +
                      " mm; calibrate again to see whether it holds, and if it does not, "
                      "check that the bed is flat and firmly mounted");
    then({verified, false});
}

std::string DeltaCycleMode::revert(int number, std::function<void(std::string what)> then) {
    if (steps_.klipper_on_host(machine_)) return revert_on_klipper_host(number, std::move(then));
    if (machine_.firmware == "klipper")
        return "revert: Klipper's settings live in printer.cfg; the box never changed them";
    const std::string name = steps_.record_name("backup.gcode");
    const auto backup = steps_.read(name);
    if (!backup)
        return "revert: cycle " + std::to_string(number) + " applied nothing (no " + name + ")";
    std::vector<std::string> lines;
    for (auto& line : lines_of(*backup))
        if (!line.empty()) lines.push_back(std::move(line));
    steps_.enter(CycleState::apply,
                 "reverting to the settings saved before cycle " + std::to_string(number));
    send_and_read_back(
        lines, [this, name, then = std::move(then)](const std::string& mismatch,
                                                    const std::vector<std::string>& reported) {
            if (!mismatch.empty()) {
                steps_.fail("revert: read-back mismatch: " + mismatch);
                return;
            }
            machine_.delta = models::geometry_from_settings(machine_.firmware, reported);
            then("reverted to " + name);
        });
    return {};
}

std::string DeltaCycleMode::revert_on_klipper_host(int number,
                                                   std::function<void(std::string what)> then) {
    const std::string name = steps_.record_name(kKlipperBackup);
    const auto backup = steps_.read(name);
    if (!backup)
        return "revert: cycle " + std::to_string(number) + " applied nothing (no " + name + ")";
    models::DeltaGeometry backed_up;
    try {
        backed_up = klipper_geometry(*backup, name);
    } catch (const std::exception& e) {
        return std::string("revert: ") + e.what();
    }
    steps_.enter(CycleState::apply,
                 "reverting printer.cfg to the one saved before cycle " + std::to_string(number));
    put_back_printer_cfg(steps_, *backup, [this, name, backed_up, then = std::move(then)] {
        read_klipper_settings([this, name, backed_up, then](const models::DeltaGeometry& in_force) {
            const std::string mismatch = models::klipper_settings_mismatch(backed_up, in_force);
            if (!mismatch.empty()) {
                steps_.fail("revert: read-back mismatch: " + mismatch);
                return;
            }
            machine_.delta = in_force;
            then("reverted to " + name);
        });
    });
    return {};
}

void DeltaCycleMode::describe_last(std::string& text, nlohmann::json& data) const {
    // A delta printer's passes: what each found, moved and did.
    auto passes = nlohmann::json::array();
    for (const auto& p : passes_) {
        text += "\npass " + std::to_string(p.pass) + ": gap varied " +
                number_text("%.3f", p.gap_range_mm) + " mm; moves the nozzle " +
                number_text("%.4f", p.xy_change_mm) + " mm in XY, " +
                number_text("%.4f", p.height_change_mm) +
                " mm in height: " + modes::pass_step_name(p.step);
        passes.push_back({{"pass", p.pass},
                          {"gap_range_mm", p.gap_range_mm},
                          {"xy_change_mm", p.xy_change_mm},
                          {"height_change_mm", p.height_change_mm},
                          {"step", modes::pass_step_name(p.step)}});
    }
    if (!passes_.empty()) data["passes"] = passes;
}

ModeResult DeltaCycleMode::result(bool) const {
    ModeResult r;
    if (!solution_) return r;
    const auto& c = solution_->fit.correction;
    r.values = {{"predicted_xy_rms_mm", c.predicted_xy_rms_mm},
                {"predicted_xy_max_mm", c.predicted_xy_max_mm}};
    for (auto& value : settings_values(solution_->after)) r.values.push_back(std::move(value));
    return r;
}

std::vector<std::string> DeltaCycleMode::result_names() {
    std::vector<std::string> names;
    for (const auto& [name, value] : settings_values({})) names.push_back(name);
    return names;
}

std::vector<std::pair<std::string, double>> settings_values(const models::DeltaGeometry& g) {
    std::vector<std::pair<std::string, double>> values;
    const char* towers[] = {"a", "b", "c"};
    auto add3 = [&](const std::string& stem, const std::string& unit,
                    const std::array<double, 3>& per_tower) {
        for (std::size_t i = 0; i < 3; ++i) {
            std::string name = stem;
            name.append("_").append(towers[i]).append("_").append(unit);
            values.emplace_back(std::move(name), per_tower[i]);
        }
    };
    values.emplace_back("diagonal_rod_mm", g.diagonal_rod_mm);
    add3("diagonal_rod_trim", "mm", g.diagonal_rod_trim_mm);
    values.emplace_back("radius_mm", g.radius_mm);
    add3("tower_angle_trim", "deg", g.tower_angle_trim_deg);
    add3("endstop_offset", "mm", g.endstop_offset_mm);
    values.emplace_back("height_mm", g.height_mm);
    return values;
}

}  // namespace calbox::firmware
