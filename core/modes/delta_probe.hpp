#pragma once
// The printer's own bed probe, read over the machine link: where to probe, the job that makes
// the printer do it and report each height, and those heights as the fit takes them. A probe
// measures the nozzle's gap over the bed before the target is printed, so the fit knows it
// everywhere and one pass suffices however unevenly the first layer lies.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/models/machine_file.hpp"
#include "core/models/machine_import.hpp"
#include "core/solve/delta_fit.hpp"

namespace calbox::modes {

// Where the box probes (machine frame, mm): the centre, six points at half the radius and
// twelve at the radius ([probe] radius_mm), the towers' directions among them.
std::vector<geometry::Point2> probe_points(const models::ProbeSettings& probe);

// The job that probes them: Marlin `G30 X Y` (it reports "Bed X: .. Y: .. Z: .."),
// RepRapFirmware a move there and `G30 S-1` ("Stopped at height .. mm"), Klipper a move there and
// `PROBE` ("probe at X,Y is z=Z": where the toolhead was when the probe triggered, its z_offset
// above the bed). Homes first.
std::vector<std::string> probe_job(const std::string& firmware,
                                   const std::vector<geometry::Point2>& points);

// The heights in the printer's replies to probe_job, in the points' order, as the fit takes
// them: the nozzle's gap over the bed when commanded to (x, y, 0), which is the reported bed
// height negated. Marlin's lines carry their own X and Y (used, and checked against where the
// box asked); RepRapFirmware's are paired with the points in order. `sigma_mm`: the probe's
// repeatability. Klipper's carry their X and Y too; its heights need the probe's z_offset
// (printer.cfg's [probe] or [bltouch], `klipper_z_offset_mm`). Throws std::invalid_argument with
// one line when the replies hold another number of heights than points, or a height reported
// elsewhere than asked.
std::vector<solve::ProbePoint> probe_from_replies(const std::string& firmware,
                                                  const std::vector<geometry::Point2>& points,
                                                  const std::vector<std::string>& replies,
                                                  double sigma_mm,
                                                  std::optional<double> klipper_z_offset_mm = {});

// A probe file for `calbox solve delta --probe`: CSV `x,y,z` lines (the gap as above; a header
// line starting with x and # comments are skipped), or a Marlin console log holding "Bed X: ..
// Y: .. Z: .." lines (G30's, or G29's at V3 or higher), whose heights are negated as above, or
// RepRapFirmware's heightmap.csv (G29's grid; points beyond its probing radius left out).
// Throws RecordError naming the line.
// Marlin's G33 report at V2 or higher (". c:.. x:.. y:.. z:.." and ". yz:.. zx:.. xy:.." lines:
// the bed's height at the centre, towards each tower and opposite each, at its calibration
// radius) is read too, given that radius (`g33_radius_mm`, Marlin's DELTA_CALIBRATION_RADIUS,
// which the report does not print): the block measured under the geometry the run ended with
// (after "rolling back" that is the first block, not the last).
std::vector<solve::ProbePoint> probe_from_file(std::string_view text, const std::string& source,
                                               std::optional<double> g33_radius_mm = std::nullopt);
// Klipper's saved [delta_calibrate] probe (SAVE_CONFIG's heightN and heightN_pos: the height the
// probe reports at the trigger and the three steppers' positions there), through the saved
// geometry: each position is steps below its tower's endstop (as Klipper's delta_calibrate keeps
// it), by the stepper's steps per mm (full steps x microsteps / rotation distance) a carriage
// height; the carriages give the effector's place; the gap at z = 0 is the height less the
// effector's z. Throws RecordError when the block holds no heights.
std::vector<solve::ProbePoint> klipper_calibrate_probe(const models::KlipperConfig& config,
                                                       const std::string& source);

// Probe points as that file's CSV (a header line, then x,y,z to 1, 1 and 0.1 micrometre).
std::string probe_to_csv(const std::vector<solve::ProbePoint>& probe);

}  // namespace calbox::modes
