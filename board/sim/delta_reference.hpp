#pragma once
// The twin's own delta kinematics, written from the formulas of Marlin's delta.cpp
// (recalc_delta_settings, inverse_kinematics) and Klipper's delta.py / mathutil.trilateration.
// It is deliberately separate from core/models: the twin judges that code.
#include <array>
#include <stdexcept>

#include "board/sim/vec.hpp"

namespace calbox::sim {

// Marlin's conventions: towers A B C at 210, 330 and 90 degrees plus angle trims, rods plus
// per-tower trims, endstop offsets <= 0 (M666), height of the nozzle over the bed centre at home.
struct DeltaParams {
    double diagonal_rod_mm = 250.0;
    std::array<double, 3> diagonal_rod_trim_mm{0, 0, 0};
    double radius_mm = 140.0;
    std::array<double, 3> tower_angle_trim_deg{0, 0, 0};
    std::array<double, 3> endstop_offset_mm{0, 0, 0};
    double height_mm = 300.0;
};

class OutOfReach : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct Tower {
    double x_mm, y_mm;  // carriage column position in the XY plane
    double rod_mm;
};
std::array<Tower, 3> towers_of(const DeltaParams& p);

// Carriage heights for an effector position (nozzle) in the machine frame; throws OutOfReach.
std::array<double, 3> reference_carriage_heights_mm(const DeltaParams& p, const Vec3& nozzle);
// Effector position for carriage heights, by trilateration (the solution below the carriages).
Vec3 reference_effector_position_mm(const DeltaParams& p, const std::array<double, 3>& carriage);

}  // namespace calbox::sim
