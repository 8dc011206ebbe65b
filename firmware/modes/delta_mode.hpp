#pragma once
// The delta mode's adapter: a printer whose own settings (M665/M666) are corrected, sent with a
// backup and a read-back, in passes until the printer holds.
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/modes/delta.hpp"
#include "core/modes/delta_records.hpp"
#include "core/image_view.hpp"
#include "firmware/cycle/cycle_mode.hpp"

namespace calbox::firmware {

// One pass of a delta printer's cycle: the target as measured, what the fit found and did, and
// the target printed again after it (the next pass's measurement, when there is one).
struct DeltaPassReport {
    int pass = 1;
    double measured_xy_rms_mm = 0, measured_xy_max_mm = 0;
    double gap_range_mm = 0;  // the nozzle's gap over the bed, as the fit found it
    double xy_change_mm = 0, height_change_mm = 0;  // what its correction moves the nozzle by
    modes::DeltaPassStep step = modes::DeltaPassStep::apply;
    std::optional<double> verify_xy_rms_mm, verify_xy_max_mm;
};

// The settings a delta correction sends, named as the Modbus result block names them
// ("diagonal_rod_trim_a_mm", ...), in its order.
std::vector<std::pair<std::string, double>> settings_values(const models::DeltaGeometry& g);

class DeltaCycleMode final : public CycleMode {
  public:
    DeltaCycleMode(models::MachineFile machine, CycleSteps& steps,
                   modes::DeltaSolveOptions solve = {}, modes::DeltaPassLimits passes = {});

    const models::MachineFile& machine() const override { return machine_; }
    modes::ModeGoal goal() const override { return modes::delta_goal(); }
    void begin() override;
    void make_target(std::function<void(std::vector<std::string>)> then) override;
    void before_target(std::function<void()> then) override;
    void measure(MeasureInput input, std::function<void()> then) override;
    void solve(std::function<void(SolveOutcome)> then) override;
    ReviewText review() const override;
    void apply(std::function<void(bool verify)> then) override;
    std::string verify_detail() const override {
        return "printing the target again on the corrected machine";
    }
    void verification_job(const std::vector<std::string>& target,
                          std::function<void(std::vector<std::string>)> then) override {
        then(target);
    }
    void judge_verification(std::function<void(VerifyOutcome)> then) override;
    std::string pass_prefix() const override;
    std::string revert(int number, std::function<void(std::string what)> then) override;
    void describe_last(std::string& text, nlohmann::json& data) const override;
    ModeResult result(bool applied) const override;
    // The values result() carries besides the predicted figures, in their order: the settings
    // its correction sent (mode_result_names).
    static std::vector<std::string> result_names();

    // The last cycle's passes, in order, and the correction sent (the last pass's).
    const std::vector<DeltaPassReport>& passes() const { return passes_; }
    const std::optional<modes::DeltaSolution>& solution() const { return solution_; }
    const std::vector<std::string>& backup() const { return backup_; }

  private:
    void read_printer_settings(std::function<void()> then);
    void probe_printer(std::function<void()> then);
    // The printer's settings report (settings_query), as the commands that set it again.
    void read_settings(std::function<void(std::vector<std::string>)> then);
    // Sends settings lines, reads the settings back and compares: `then(mismatch, reported)`,
    // the mismatch empty when they agree. A send that fails (the link gone mid-batch) calls
    // `failed` with why; without it the cycle is in error.
    void send_and_read_back(const std::vector<std::string>& lines,
                            std::function<void(std::string, std::vector<std::string>)> then,
                            std::function<void(const std::string&)> failed = {});
    void restore_backup(const std::string& why);
    void read_klipper_settings(std::function<void(models::DeltaGeometry)> then);
    std::optional<double> klipper_probe_z_offset_mm_;  // from the settings in force
    void apply_on_klipper_host(std::function<void(bool verify)> then);
    void restore_klipper_config(const std::string& backup, const std::string& written,
                                const std::string& why);
    std::string revert_on_klipper_host(int number, std::function<void(std::string what)> then);
    // Each pass's printer.cfg as it was before the pass wrote it.
    static constexpr const char* kKlipperBackup = "backup-printer.cfg";
    std::string pass_file(const std::string& what) const;

    models::MachineFile machine_;
    CycleSteps& steps_;
    modes::DeltaSolveOptions solve_options_;
    modes::DeltaPassLimits pass_limits_;
    // This cycle's working data.
    std::vector<solve::ProbePoint> probe_;  // the printer's own probe's, this cycle's first pass
    std::optional<modes::DeltaMeasurementsRecord> measurements_;
    std::vector<DeltaPassReport> passes_;
    std::optional<modes::DeltaSolution> solution_;
    std::vector<std::string> backup_;  // the settings before, as commands (M665, M666)
};

// The delta's overlay: each marker's outline, each corner's placement error as an arrow (magnified,
// with its factor printed) and each bar between its measured end ticks with its length. PNG bytes.
std::string delta_overlay_png(const vision::GrayView& photo,
                              const modes::DeltaMeasurement& measured,
                              const geometry::CameraModel& camera, const geometry::BedPlane& plane);

}  // namespace calbox::firmware
