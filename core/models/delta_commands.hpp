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
std::vector<std::string> firmware_commands(const std::string& firmware,
                                           const DeltaGeometry& g);  // by name

// The settings lines of a Marlin M503 report ("echo:  M665 L250.000 R140.000 ..."), as commands
// that would set them again: "M665 ..." and "M666 ...", in the order reported.
std::vector<std::string> marlin_settings_from_report(const std::vector<std::string>& replies);
// Compares what was sent against what the printer reports, word by word, within the precision
// Marlin prints (3 decimals): empty when they agree, else one line naming the first difference.
std::string settings_mismatch(const std::vector<std::string>& sent,
                              const std::vector<std::string>& reported);

}  // namespace calbox::models
