#pragma once
// Linear delta kinematics in Marlin's conventions (delta.cpp): towers A, B, C at 210, 330 and
// 90 degrees plus angle trims, diagonal rods plus per-tower trims, carriage height
// z + sqrt(rod^2 - dx^2 - dy^2); forward kinematics by trilateration. Conversions to and from
// RepRapFirmware's and Klipper's conventions.
#include <array>
#include <stdexcept>
#include <string>

#include "core/geometry/types.hpp"
#include "core/models/machine_file.hpp"

namespace calbox::models {

using DeltaGeometry = DeltaSettings;  // the machine file's [delta] keys

class UnreachableError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

std::array<double, 3> carriage_heights_mm(const DeltaGeometry& g, const geometry::Point3& nozzle);
geometry::Point3 effector_position_mm(const DeltaGeometry& g,
                                      const std::array<double, 3>& carriage_mm);

// Where the nozzle really goes on a printer whose true geometry is `truth` when its firmware,
// believing `firmware`, is commanded to `commanded` (after G28: each carriage homes to its
// physical endstop and moves down by the firmware's M666 offset).
geometry::Point3 actual_position_mm(const DeltaGeometry& truth, const DeltaGeometry& firmware,
                                    const geometry::Point3& commanded);

// The gauges a camera imposes (DESIGN.md): angle trims and rod trims sum to zero (the common
// rod part is the rod length), the largest endstop offset is zero (the common part is height).
DeltaGeometry in_gauge(const DeltaGeometry& g);

// RepRapFirmware: per-tower diagonals, the Z tower as the angle reference, M666 positive where
// Marlin's is negative.
struct RrfDelta {
    std::array<double, 3> diagonal_mm{};
    double radius_mm = 0;
    double height_mm = 0;
    double x_tower_angle_deg = 0, y_tower_angle_deg = 0;  // Z tower's is zero
    std::array<double, 3> endstop_adjustment_mm{};
};
RrfDelta to_rrf(const DeltaGeometry& g);
DeltaGeometry from_rrf(const RrfDelta& r);  // in gauge

// Klipper: absolute tower angles, per-stepper arm lengths, position_endstop per stepper.
struct KlipperDelta {
    double delta_radius_mm = 0;
    std::array<double, 3> arm_length_mm{};
    std::array<double, 3> angle_deg{};
    std::array<double, 3> position_endstop_mm{};
};
KlipperDelta to_klipper(const DeltaGeometry& g);
DeltaGeometry from_klipper(const KlipperDelta& k);  // in gauge

}  // namespace calbox::models
