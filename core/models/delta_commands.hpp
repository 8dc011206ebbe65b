#pragma once
// A delta geometry as each firmware takes it: the exact lines to send, in order.
#include <string>
#include <vector>

#include "core/models/delta.hpp"

namespace calbox::models {

// Marlin: M665 L R H X Y Z A B C, M666 X Y Z (offsets <= 0, common part in H), M500.
std::vector<std::string> marlin_commands(const DeltaGeometry& g);
// RepRapFirmware: M665 L a:b:c R H X Y Z (Z tower the angle reference), M666 X Y Z, M500.
std::vector<std::string> rrf_commands(const DeltaGeometry& g);
// Klipper: a printer.cfg snippet ([printer] delta_radius, [stepper_*] arm_length, angle,
// position_endstop), one line per element.
std::vector<std::string> klipper_snippet(const DeltaGeometry& g);
// printer.cfg with `g` where Klipper's SAVE_CONFIG keeps what it saves (klipper_saved_values: the
// block's other values, a bed mesh or DELTA_CALIBRATE's probe, stay).
std::string klipper_saved_config(const std::string& printer_cfg, const DeltaGeometry& g);
// Compares the geometry sent (klipper_saved_config) with the one Klipper took (its settings in
// force, read back), in Klipper's own values to the 3 decimals sent: empty when they agree, else
// one line naming the first difference.
std::string klipper_settings_mismatch(const DeltaGeometry& sent, const DeltaGeometry& in_force);
std::vector<std::string> firmware_commands(const std::string& firmware,
                                           const DeltaGeometry& g);  // by name

// The lines that make a firmware report the delta settings in force: Marlin's M503;
// RepRapFirmware's M665 and M666 without parameters (its M503 lists config.g, not what is in
// force). Throws std::invalid_argument for Klipper, whose settings live in printer.cfg.
std::vector<std::string> settings_query(const std::string& firmware);
// The settings in that report, as the commands that would set them again (M665, then M666):
// Marlin's "echo:  M665 L250.000 R140.000 ..." lines as they are; RepRapFirmware's "Diagonals
// 250.000:250.000:250.000, delta radius 140.000, ..." and "Endstop adjustments X0.00 ..."
// rewritten as M665 and M666. Empty when the report holds neither.
std::vector<std::string> settings_from_report(const std::string& firmware,
                                              const std::vector<std::string>& replies);
// The geometry that settings commands (settings_from_report's) put in force, in gauge: the
// printer as it is set now, whatever a machine file says. Throws std::invalid_argument naming
// what is missing (M665's L, R or H; M666).
DeltaGeometry geometry_from_settings(const std::string& firmware,
                                     const std::vector<std::string>& commands);
// Compares what was sent against what the printer reports (settings_from_report), word by word
// and list element by element, within 1.5 units of the last digit the firmware prints (Marlin:
// 3 decimals; RepRapFirmware: 3 for M665, 2 for M666): empty when they agree, else one line
// naming the first difference.
std::string settings_mismatch(const std::string& firmware, const std::vector<std::string>& sent,
                              const std::vector<std::string>& reported);

}  // namespace calbox::models
