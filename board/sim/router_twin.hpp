#pragma once
// A gantry router with hidden quasi-static errors, and the twin's judgement of it. The errors
// are the twin's own small model of a real machine, composed exactly (rotation matrices, not
// first order) and not from the code it judges: each axis's scale, the gantry out of square,
// each axis bowed (a parabola through its ends), the gantry yawing as it travels, pitch and roll
// of the gantry and the carriage acting over the tool's length (the Abbe errors), a lead
// screw's cyclic error, and backlash in both drives.
#include <array>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "board/sim/delta_judge.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/scenes.hpp"
#include "core/jobs/compensate.hpp"
#include "core/models/machine_file.hpp"

namespace calbox::sim {

struct RouterTruth {
    double travel_x_mm = 300, travel_y_mm = 300;
    double scale_x = 0, scale_y = 0;  // relative: 0.002 moves 0.2 % too far
    double squareness_rad = 0;        // the gantry's travel leans towards +x
    double bow_x_mm = 0;  // the carriage's path off the line through its ends, mid-travel, in y
    double bow_y_mm = 0;  // the gantry's path, mid-travel, in x
    double gantry_yaw_rad_per_mm = 0;
    double gantry_pitch_rad_per_mm = 0, gantry_roll_rad_per_mm = 0;      // about x, about y
    double carriage_pitch_rad_per_mm = 0, carriage_roll_rad_per_mm = 0;  // about y, about x
    double tool_length_mm = 90;  // the tool point below the carriage's guides at Z0
    double screw_error_mm = 0;   // amplitude of each lead screw's cyclic error
    double screw_lead_mm = 5;
    double backlash_x_mm = 0, backlash_y_mm = 0;
    // Where the operator touched off G54, in grbl's machine coordinates (after homing to the
    // back right corner they are negative): the controller reports it to `$#`. The errors above
    // are in the work frame, so it moves nothing the twin makes.
    double g54_x_mm = 0, g54_y_mm = 0;
    // G54's Z zero in machine coordinates: the bed's (the spoilboard's) top, touched off there.
    double g54_z_mm = 0;
};

// A seeded router with errors of the seed paper's size: around 1.5 mm mean error norm over a
// 300 x 300 mm work area, once the machine's placement is taken out.
RouterTruth random_router_truth(unsigned seed, double travel_x_mm = 300, double travel_y_mm = 300);

// Where the tool point really is for a commanded position, the drives having last moved
// towards +x / +y when `moving_positive` says so (backlash lags behind the motion).
Vec3 router_tool_position_mm(const RouterTruth& truth, const Vec3& commanded,
                             std::array<bool, 2> moving_positive);

class RouterTwin final : public MachineTwin {
  public:
    explicit RouterTwin(const RouterTruth& truth) : truth_(truth) {}
    void home() override;
    bool homed() const override { return homed_; }
    Vec3 position_after_homing_mm() const override { return {0, 0, 0}; }
    // Keeps which way each drive last moved: the commanded positions come in the order the
    // machine moves through them.
    Vec3 actual_position_mm(const Vec3& commanded_in_g54) const override;
    std::optional<std::vector<std::string>> settings_command(const gcode::Line& line) override;
    // grbl's `$#`: the work coordinate systems' zeros in machine coordinates.
    std::optional<std::vector<std::string>> system_command(std::string_view text) override;
    const RouterTruth& truth() const { return truth_; }
    Vec3 work_zero_mm() const override { return {g54_x_mm_, g54_y_mm_, truth_.g54_z_mm}; }
    // A sheet `thickness_mm` thick lies on the bed (the bed's frame: the truth's work frame).
    void lay_sheet(const StockSheet& sheet, double thickness_mm);
    // A touch probe at the tool point: it touches the sheet's top where the tool is over the
    // sheet, else the bed's (work Z 0), where the tool really is (the gantry's tilts move the
    // tool's height with X and Y); each touch off by 0.002 mm (standard deviation, a fixed seed).
    Vec3 probe_down(const Vec3& from, double to_z) override;

  private:
    RouterTruth truth_;
    // G54's zero now, machine coordinates: the operator's touch-off (the truth's) until a G10 L2
    // P1 moves it; the work frame the errors are in stays where the truth put it.
    double g54_x_mm_ = truth_.g54_x_mm, g54_y_mm_ = truth_.g54_y_mm;
    bool homed_ = true;  // a router's work zero is set by hand; jobs need not home it
    std::optional<std::array<Vec2, 4>> sheet_corners_;  // the laid sheet's, counter-clockwise
    double sheet_thickness_mm_ = 0;
    std::mt19937 probe_noise_{20261202};
    mutable Vec3 last_commanded_{0, 0, 0};
    mutable std::array<bool, 2> moving_positive_{true, true};
};

// The holes a drilling job makes on the router: where the tool really was at the bottom of
// each plunge, in the order the job drills them.
std::vector<Vec2> drilled_hole_centres_mm(RouterTwin& twin, const std::string& job);

// The strokes of a drilling job as the camera sees them: each cut laid on the sheet's top.
std::vector<StrokeSegment> holes_on_the_sheet(const std::vector<Stroke>& cuts,
                                              double surface_height_mm);

// How well a drilling job lands on the points it was meant to drill, in the twin's truth: the
// job (compensated or not) run on the router, each hole against its intended point, the
// machine's placement taken out (the work's zero and heading are set by hand).
using RouterJudgement = PlacedJudgement;
RouterJudgement judge_router(const RouterTruth& truth, const std::vector<Vec2>& intended_mm,
                             const std::string& job);

}  // namespace calbox::sim

namespace calbox::sim {

// The twin's verdict on a fresh job: holes half a pitch off the machine's target grid (none of
// them a hole the calibration saw), drilled as commanded, and with `correct` through the
// compensated G-code (calbox compensate's own machinery, the code being judged).
struct RouterVerdict {
    RouterJudgement before;
    std::optional<RouterJudgement> after;
    std::size_t holes = 0;
};
RouterVerdict judge_router_fresh_holes(const RouterTruth& truth, const models::MachineFile& machine,
                                       const jobs::Correction* correct);

// The same verdict on a cartesian printer or gantry laser (its twin has no backlash): each fresh
// point commanded (through `correct` when given) and put where the machine really puts it.
RouterVerdict judge_cartesian_fresh_points(const CartesianErrors& truth,
                                           const models::MachineFile& machine,
                                           const jobs::Correction* correct);
// The same on a cartesian twin as its firmware is set (its truth and firmware copied).
RouterVerdict judge_cartesian_fresh_points(CartesianTwin twin, const models::MachineFile& machine,
                                           const jobs::Correction* correct);

}  // namespace calbox::sim
