#pragma once
// The galvo mode's adapter: the scanner's field corrected by a table the box keeps
// (galvo-table.json) and sends jobs through; verified on the grid burned through it.
#include <optional>

#include "core/modes/galvo.hpp"
#include "core/image_view.hpp"
#include "firmware/modes/kept_correction.hpp"

namespace calbox::firmware {

constexpr const char* kGalvoTableFile = "galvo-table.json";
constexpr const char* kNoGalvoTable = "none\n";

// A table as a controller reads it from its registers: the node count and the rectangle, then
// each node's command x and y, row by row (docs/devices.md, "The table over Modbus").
std::vector<float> table_registers(const models::CorrectionTable& table);

class GalvoCycleMode final : public KeptCorrectionMode {
  public:
    GalvoCycleMode(models::MachineFile machine, CycleSteps& steps);
    const models::MachineFile& machine() const override { return machine_; }
    modes::ModeGoal goal() const override { return modes::galvo_goal(); }
    void begin() override;
    void make_target(std::function<void(std::vector<std::string>)> then) override;
    void before_target(std::function<void()> then) override { then(); }
    void measure(MeasureInput input, std::function<void()> then) override;
    void solve(std::function<void(SolveOutcome)> then) override;
    ReviewText review() const override;
    void judge_verification(std::function<void(VerifyOutcome)> then) override;
    void describe_last(std::string&, nlohmann::json&) const override {}
    ModeResult result(bool applied) const override;
    // The kept table in ModeResult::table (table_registers), from holding register 1000.
    static ModeTable result_table();

    const std::optional<modes::GalvoSolution>& solution() const { return solution_; }

  protected:
    std::string kept_text() const override;
    jobs::Correction correction() const override;
    jobs::Area measured_area() const override;
    jobs::JobFrame target_frame() const override;
    jobs::KeptCorrection correction_of(const std::string& kept_text) const override;

  private:
    models::MachineFile machine_;
    std::optional<modes::GalvoMeasurement> measured_;
    std::optional<modes::GalvoSolution> solution_;
};

// The galvo's overlay: each mark measured (green; every fifth labelled column,row) and each extra
// blob (orange). PNG bytes.
std::string galvo_overlay_png(const vision::GrayView& photo,
                              const modes::GalvoMeasurement& measured,
                              const models::MachineFile& machine,
                              const geometry::CameraModel& camera, const geometry::BedPlane& plane);

}  // namespace calbox::firmware
