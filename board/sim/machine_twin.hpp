#pragma once
// Simulated machines: where the nozzle or tool really is for a commanded position, given the
// hidden true geometry and what the firmware believes.
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "board/sim/delta_reference.hpp"
#include "core/gcode/gcode_line.hpp"

namespace calbox::sim {

class MachineError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// A probing cycle grbl stops with its alarm: 4, the probe touching before the cycle began; 5, no
// touch within the cycle's travel.
class ProbeAlarm : public MachineError {
  public:
    ProbeAlarm(int grbl_alarm, const std::string& what) : MachineError(what), alarm(grbl_alarm) {}
    int alarm;
};

class MachineTwin {
  public:
    virtual ~MachineTwin() = default;
    virtual void home() = 0;  // G28
    virtual bool homed() const = 0;
    virtual Vec3 position_after_homing_mm() const = 0;  // commanded position after G28
    // Where the nozzle/tool really is for a commanded machine position; throws OutOfReach.
    virtual Vec3 actual_position_mm(const Vec3& commanded) const = 0;
    // Machine-specific settings commands (M665, M666, M500, M503): the reply lines, or empty
    // when the command is not one of them.
    virtual std::optional<std::vector<std::string>> settings_command(const gcode::Line& line) = 0;
    // A grbl system command ("$#"): its reply lines, or empty when the machine has none such.
    virtual std::optional<std::vector<std::string>> system_command(std::string_view text) {
        (void)text;
        return std::nullopt;
    }
    // G30: probes the bed at the commanded position `at` (its X and Y; Z is where the nozzle
    // ends up after) and returns the reply lines. Throws MachineError when the machine has no
    // probe or does not take the command so.
    virtual std::vector<std::string> probe_bed(const gcode::Line& line, Vec3& at);
    // G54's zero in machine coordinates now: G53's moves and a probe's reports are in machine
    // coordinates, every other move in G54's.
    virtual Vec3 work_zero_mm() const { return {}; }
    // grbl's G38.2 straight down from `from` (commanded, in G54) towards Z `to_z`: the commanded
    // position at which the probe touched. Throws ProbeAlarm when it touched before moving or
    // not at all, MachineError when the machine has no such probe.
    virtual Vec3 probe_down(const Vec3& from, double to_z);
};

// Whose settings commands the delta twin speaks. Marlin: M665 L R H X Y Z A B C (rod trims),
// M666 offsets <= 0, M503 reports. RepRapFirmware (LinearDeltaKinematics): M665 L a:b:c (one
// rod per tower) R H B X Y Z, M666 X Y Z adjustments of either sign (+ raises the endstop, so it
// is Marlin's offset negated), each reporting its settings when given no parameters.
// Klipper: no settings commands at all (its geometry is printer.cfg's, taken at a restart).
enum class DeltaDialect { marlin, rrf, klipper };

// A linear delta in Marlin's conventions. G28 moves each carriage to its physical endstop,
// then down by the firmware's M666 offset, and declares the nozzle at (0, 0, height).
class DeltaTwin final : public MachineTwin {
  public:
    DeltaTwin(const DeltaParams& truth, const DeltaParams& firmware,
              DeltaDialect dialect = DeltaDialect::marlin);
    void home() override;
    bool homed() const override { return homed_; }
    Vec3 position_after_homing_mm() const override { return {0, 0, firmware_.height_mm}; }
    Vec3 actual_position_mm(const Vec3& commanded) const override;
    std::optional<std::vector<std::string>> settings_command(const gcode::Line& line) override;
    // A probe at the nozzle, as a good inductive one: each reading off by a repeatable-looking
    // 0.004 mm (standard deviation, from a fixed seed), then printed as the firmware prints it
    // (Marlin "Bed X: .. Y: .. Z: .." to 0.01 mm; RepRapFirmware's G30 S-1 "Stopped at height
    // .. mm" to 0.001 mm). The height is the commanded Z at which the nozzle touches the bed.
    std::vector<std::string> probe_bed(const gcode::Line& line, Vec3& at) override;

    const DeltaParams& firmware() const { return firmware_; }
    const DeltaParams& stored_firmware() const { return stored_; }  // as of the last M500
    DeltaDialect dialect() const { return dialect_; }
    // Klipper's [probe] z_offset: its PROBE reports the toolhead's height at the trigger.
    void set_klipper_probe_z_offset(double mm) { klipper_probe_z_offset_mm_ = mm; }
    // Shifts the firmware's height so that commanded Z = 0 touches the bed at its centre, as a
    // paper test does.
    void zero_height_at_centre();
    // What an owner's paper test leaves, the classic manual way: the endstop offsets (M666)
    // and the height set so that commanded Z = 0 touches the bed near each tower (at
    // `tower_points_radius_mm`), the radius so that it touches at the centre too; between those
    // points the bed is as the rest of the geometry makes it.
    void level_by_paper(double tower_points_radius_mm);
    // What a probe routine (Marlin's G33, RepRapFirmware's G32) leaves: radius, height, endstop
    // offsets and two angle trims set so that the nozzle's height at the centre, twelve points
    // at `outer_radius_mm` and six at `inner_radius_mm` is as flat as they can make it; the
    // rods, which a probe cannot see, stay wrong.
    void level_by_probe(double outer_radius_mm, double inner_radius_mm);
    // The commands that set the stored settings again, in the twin's dialect (its EEPROM or
    // config-override.g).
    std::vector<std::string> stored_settings_commands() const;

  private:
    // Gauss-Newton on the firmware's settings `free` makes of a vector, to zero the nozzle's
    // height at `points` commanded to Z = 0.
    template <typename Settings>
    void level(const std::vector<Vec3>& points, int unknowns, Settings free);
    std::optional<std::vector<std::string>> rrf_settings_command(const gcode::Line& line);
    DeltaParams truth_, firmware_, stored_;
    DeltaDialect dialect_;
    double klipper_probe_z_offset_mm_ = 0;
    bool homed_ = false;
    std::array<double, 3> home_physical_mm_{};  // carriage heights in the true frame at home
    std::array<double, 3> home_logical_mm_{};   // what the firmware believes they are
    std::mt19937 probe_noise_{20261125};
};

// A cartesian machine with small axis scale errors and an out-of-square X/Y pair.
struct CartesianErrors {
    double scale_error_x = 0;  // relative: actual = commanded * (1 + error)
    double scale_error_y = 0;
    double squareness_error_deg = 0;  // the Y axis leans towards +X by this angle
};

// What a Klipper cartesian printer's firmware holds, in the twin's terms: each axis's travel per
// commanded mm (the rotation_distance its owner's printer.cfg had, which the truth's scale errors
// are against, over the one in force), and the skew in force (Klipper moves x by -xy_skew per mm
// of y before its kinematics). A Marlin twin keeps the identity.
struct CartesianFirmware {
    double travel_x = 1, travel_y = 1;
    double xy_skew = 0;
};

class CartesianTwin final : public MachineTwin {
  public:
    // `grbl`: a gantry laser's grbl, homing off ($22=0, as most diode lasers run): it moves from
    // where it stands, ends a program at M2 or M30 and reports its offsets to `$#`; otherwise a
    // printer's firmware, which refuses a move before G28.
    explicit CartesianTwin(const CartesianErrors& truth, const CartesianFirmware& firmware = {},
                           bool grbl = false)
        : truth_(truth), firmware_(firmware), grbl_(grbl), homed_(grbl) {}
    const CartesianFirmware& firmware() const { return firmware_; }
    void set_skew(double xy_skew) { firmware_.xy_skew = xy_skew; }
    void home() override { homed_ = true; }
    bool homed() const override { return homed_; }
    Vec3 position_after_homing_mm() const override { return {0, 0, 0}; }
    Vec3 actual_position_mm(const Vec3& commanded) const override;
    std::optional<std::vector<std::string>> settings_command(const gcode::Line& line) override;
    // grbl's `$#`: G54 at the machine's zero.
    std::optional<std::vector<std::string>> system_command(std::string_view text) override;

  private:
    CartesianErrors truth_;
    CartesianFirmware firmware_;
    bool grbl_ = false;
    bool homed_ = false;
};

std::vector<std::string> marlin_delta_report(const DeltaParams& p);  // M503's delta lines
// grbl's reply to `$#` with G54's zero at (x, y, z) and every other offset at zero.
std::vector<std::string> grbl_offsets_report(double g54_x_mm, double g54_y_mm, double g54_z_mm = 0);

}  // namespace calbox::sim
