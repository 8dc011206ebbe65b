#pragma once
// The planar mode's adapter (routers, cartesian machines): the machine's quasi-static error
// model, kept by the box (planar-result.json) and compensated into the jobs sent through it;
// verified on the grid drilled through it. The firmware's own scale and skew settings are shown
// beside it (firmware.txt), not sent: both would correct twice.
#include <optional>

#include "core/modes/planar.hpp"
#include "firmware/modes/kept_correction.hpp"

namespace calbox::firmware {

constexpr const char* kPlanarResultFile = "planar-result.json";
constexpr const char* kNoPlanarResult = "none\n";

class PlanarCycleMode final : public KeptCorrectionMode {
  public:
    PlanarCycleMode(models::MachineFile machine, CycleSteps& steps);
    const models::MachineFile& machine() const override { return machine_; }
    modes::ModeGoal goal() const override { return modes::planar_goal(); }
    void begin() override;
    void make_target(std::function<void(std::vector<std::string>)> then) override;
    void before_target(std::function<void()> then) override { then(); }
    void measure(MeasureInput input, std::function<void()> then) override;
    void solve(std::function<void(SolveOutcome)> then) override;
    ReviewText review() const override;
    void judge_verification(std::function<void(VerifyOutcome)> then) override;
    void describe_last(std::string&, nlohmann::json&) const override {}
    ModeResult result(bool) const override { return {}; }

    const std::optional<modes::PlanarSolution>& solution() const { return solution_; }

  protected:
    std::string kept_text() const override;
    targets::Correction correction() const override;
    targets::Covers covers() const override;
    targets::KeptCorrection correction_of(const std::string& kept_text) const override;

  private:
    models::MachineFile machine_;
    std::optional<modes::PlanarMeasurement> measured_;
    std::optional<modes::PlanarSolution> solution_;
};

}  // namespace calbox::firmware
