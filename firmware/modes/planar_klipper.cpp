// The planar mode on a Klipper printer behind its host: the fitted linear part goes into the
// printer's own settings (rotation_distance in printer.cfg's SAVE_CONFIG block, the skew through
// SET_SKEW, SKEW_PROFILE SAVE and SAVE_CONFIG), printer.cfg as it was is the cycle's backup, and
// what Klipper took is read back.
#include "core/number_text.hpp"
#include "firmware/modes/klipper_host.hpp"
#include "firmware/modes/planar_mode.hpp"

namespace calbox::firmware {
namespace {

std::string describe(const models::KlipperCartesian& k) {
    return "rotation_distance X " + number_text("%.6f", k.rotation_distance_x_mm) + " Y " +
           number_text("%.6f", k.rotation_distance_y_mm) + ", skew profile " +
           models::kKlipperSkewProfile + " " +
           (k.xy_skew ? "xy_skew " + number_text("%.7f", *k.xy_skew) : std::string("not saved"));
}

std::string load_skew(const models::KlipperCartesian& k) {
    // Klipper starts with no skew in force: a profile is in force once loaded.
    return k.xy_skew ? std::string("SKEW_PROFILE LOAD=") + models::kKlipperSkewProfile
                     : std::string("SET_SKEW CLEAR=1");
}

}  // namespace

void PlanarCycleMode::read_klipper_settings(std::function<void(models::KlipperCartesian)> then) {
    steps_.read_settings_in_force<models::KlipperCartesian>(
        [](const std::string& text) {
            return models::read_klipper_cartesian("Klipper's settings in force", text);
        },
        std::move(then));
}

// The target is made with the printer's settings in force known: its profile loaded, or none.
void PlanarCycleMode::before_target(std::function<void()> then) {
    controller_work_zero_.reset();
    if (machine_.firmware == "grbl") {
        // The frame the target runs in: grbl tells its G54 zero.
        steps_.send_commands({"$#"}, [this, then = std::move(then)](const JobOutcome& o) {
            controller_work_zero_ = modes::grbl_work_zero_of(o.replies, "G54");
            if (controller_work_zero_)
                steps_.log("the controller's G54 zero ($#): machine X" +
                           number_text("%.3f", controller_work_zero_->x) + " Y" +
                           number_text("%.3f", controller_work_zero_->y) + " mm");
            else
                steps_.log(
                    "the controller did not report its G54 zero ($#): the machine file's "
                    "is recorded as the frame");
            then();
        });
        return;
    }
    if (!steps_.klipper_on_host(machine_)) {
        then();
        return;
    }
    read_klipper_settings([this, then = std::move(then)](const models::KlipperCartesian& k) {
        if (!k.takes_skew) {
            steps_.fail(
                "printer.cfg has no [skew_correction] section: add one (it needs no options) "
                "so that Klipper takes the skew the box measures");
            return;
        }
        klipper_now_ = k;
        steps_.log("the printer's settings in force: " + describe(k));
        steps_.send_commands({load_skew(k)}, [then](const JobOutcome&) { then(); });
    });
}

ReviewText PlanarCycleMode::klipper_review() const {
    const auto& f = *firmware_;
    ReviewText r;
    r.detail = "predicted after " + number_text("%.4f", f.mean_left_mm) + " mm mean";
    r.proposed = "proposed: Klipper's " + describe(*klipper_sent_) + " (now " +
                 describe(*klipper_now_) + "); error norm now " +
                 number_text("%.4f", f.mean_before_mm) + " mm mean, predicted after " +
                 number_text("%.4f", f.mean_left_mm) + " mm mean";
    r.details = models::klipper_skew_commands(*klipper_sent_->xy_skew);
    r.details.emplace_back("SAVE_CONFIG");
    for (const auto& v : models::klipper_travel_values(*klipper_sent_))
        r.details.push_back("#*# [" + v.section + "] " + v.key + " = " + v.value);
    r.screen = ReviewScreen{{"X " + number_text("%+.3f", 100 * f.scale_x) + "% Y " +
                                 number_text("%+.3f", 100 * f.scale_y) + "%",
                             "skew " + number_text("%+.3f", 1000 * f.skew) + " mrad"},
                            number_text("%.3f", f.mean_before_mm),
                            number_text("%.3f", f.mean_left_mm)};
    return r;
}

void PlanarCycleMode::apply(std::function<void(bool verify)> then) {
    if (steps_.klipper_on_host(machine_))
        apply_on_klipper_host(std::move(then));
    else
        KeptCorrectionMode::apply(std::move(then));
}

std::string PlanarCycleMode::verify_detail() const {
    return steps_.klipper_on_host(machine_) ? "printing the grid again with Klipper's new settings"
                                            : KeptCorrectionMode::verify_detail();
}

void PlanarCycleMode::verification_job(const std::vector<std::string>& target,
                                       std::function<void(std::vector<std::string>)> then) {
    if (steps_.klipper_on_host(machine_))
        then(target);  // the printer corrects itself now
    else
        KeptCorrectionMode::verification_job(target, std::move(then));
}

// The rotation distances first, in the box's own write of printer.cfg (only while it is still the
// file read): an upload the host refuses leaves the file untouched. Then the skew, which Klipper
// saves itself over the file it took.
void PlanarCycleMode::apply_on_klipper_host(std::function<void(bool verify)> then) {
    write_printer_cfg(
        steps_,
        {[this](const std::string& read) {
             return models::klipper_saved_values(read,
                                                 models::klipper_travel_values(*klipper_sent_));
         },
         steps_.record_name(kKlipperBackup), steps_.record_name("printer.cfg"),
         "writing the rotation distances into printer.cfg's SAVE_CONFIG block and restarting "
         "Klipper",
         [this, then = std::move(then)](const std::string& backup, const std::string&) {
             save_klipper_skew(backup, then);
         },
         [this](const std::string& backup, const std::string&, const std::string& why) {
             restore_klipper_config(backup, why);
         }});
}

void PlanarCycleMode::save_klipper_skew(const std::string& backup,
                                        const std::function<void(bool verify)>& then) {
    steps_.log("saving the skew profile " + std::string(models::kKlipperSkewProfile) +
               " (SET_SKEW, SKEW_PROFILE SAVE, SAVE_CONFIG)");
    steps_.ask_machine(
        [sent = *klipper_sent_](MachineLink& m, MachineLink::Done done) {
            m.save_config_after(models::klipper_skew_commands(*sent.xy_skew), std::move(done));
        },
        [this, then, backup](const JobOutcome& saved) {
            if (!saved.ok) {
                restore_klipper_config(backup, "apply: " + saved.error);
                return;
            }
            // The restart left no skew in force: the new profile is loaded, then all of it read
            // back.
            steps_.send_commands({load_skew(*klipper_sent_)}, [this, then,
                                                               backup](const JobOutcome&) {
                read_klipper_settings([this, then, backup](const models::KlipperCartesian& k) {
                    const std::string mismatch =
                        models::klipper_cartesian_mismatch(*klipper_sent_, k);
                    if (!mismatch.empty()) {
                        restore_klipper_config(backup, "apply: read-back mismatch: " + mismatch);
                        return;
                    }
                    klipper_now_ = k;
                    steps_.notice(std::string("Klipper puts a skew profile in force only when "
                                              "told: add SKEW_PROFILE LOAD=") +
                                  models::kKlipperSkewProfile +
                                  " to your PRINT_START macro (it is loaded until Klipper "
                                  "restarts)");
                    then(true);
                });
            });
        },
        false);
}

void PlanarCycleMode::restore_klipper_config(const std::string& backup, const std::string& why) {
    restore_printer_cfg(
        steps_, backup,
        [backup](const std::string& now) {
            try {
                return models::klipper_changed_only_travel_and_skew(backup, now);
            } catch (const std::exception&) {
                return false;  // a file the reader refuses is nobody's the box should overwrite
            }
        },
        why);
}

std::string PlanarCycleMode::revert(int number, std::function<void(std::string what)> then) {
    if (steps_.klipper_on_host(machine_)) return revert_on_klipper_host(number, std::move(then));
    return KeptCorrectionMode::revert(number, std::move(then));
}

std::string PlanarCycleMode::revert_on_klipper_host(int number,
                                                    std::function<void(std::string what)> then) {
    const std::string name = steps_.record_name(kKlipperBackup);
    const auto backup = steps_.read(name);
    if (!backup)
        return "revert: cycle " + std::to_string(number) + " applied nothing (no " + name + ")";
    models::KlipperCartesian backed_up;
    try {
        backed_up = models::read_klipper_cartesian(name, *backup);
    } catch (const std::exception& e) {
        return std::string("revert: ") + e.what();
    }
    steps_.enter(CycleState::apply,
                 "reverting printer.cfg to the one saved before cycle " + std::to_string(number));
    put_back_printer_cfg(steps_, *backup, [this, name, backed_up, then = std::move(then)] {
        steps_.send_commands({load_skew(backed_up)}, [this, name, backed_up,
                                                      then](const JobOutcome&) {
            read_klipper_settings([this, name, backed_up, then](const models::KlipperCartesian& k) {
                const std::string mismatch = models::klipper_cartesian_mismatch(backed_up, k);
                if (!mismatch.empty()) {
                    steps_.fail("revert: read-back mismatch: " + mismatch);
                    return;
                }
                klipper_now_ = k;
                then("reverted to " + name);
            });
        });
    });
    return {};
}

}  // namespace calbox::firmware
