#pragma once
// A galvo laser scanner with hidden field distortion, and the twin's judgement of it. The
// distortion is the twin's own small model of what real scanners show: the two mirrors'
// separation (a line of constant commanded x bows outwards with y), the f-theta lens's residual
// pincushion or barrel, each axis's gain and offset, skew between the axes, a rotation of the
// head on its mount, and a smooth ripple from the optics. None of it comes from the code it
// judges.
#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "board/sim/delta_judge.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/scenes.hpp"

namespace calbox::sim {

struct GalvoTruth {
    double field_size_mm = 110;     // the field the scanner addresses, scanner mm
    double gain_x = 0, gain_y = 0;  // relative: 0.002 marks 0.2 % long
    double offset_x_mm = 0, offset_y_mm = 0;
    double skew_deg = 0;        // the y axis leans towards +x
    double rotation_deg = 0;    // the head turned on its mount
    double mirror_bow_mm = 0;   // x grows by this at the field's corners (two mirrors)
    double lens_radial_mm = 0;  // outward at the corners (+ pincushion, - barrel)
    double ripple_mm = 0;       // amplitude of the optics' smooth ripple
    double ripple_period_mm = 60;
    double ripple_phase_rad = 0;
    double substrate_height_mm = 0;  // marks lie on the substrate's top (Zp)
    bool x_reversed = false;         // the x mirror's drive wired backwards
};

// A seeded scanner with errors of the size real uncorrected heads show: around half a millimetre
// at the corners of a 110 mm field.
GalvoTruth random_galvo_truth(unsigned seed, double field_size_mm = 110);

// Where the beam lands for a command in scanner millimetres.
Vec2 galvo_mark_position_mm(const GalvoTruth& truth, Vec2 command_mm);

// The scanner as the G-code twin drives it: no homing, every position through the field map, z
// ignored (the beam marks the substrate wherever the lens focuses it).
class GalvoTwin final : public MachineTwin {
  public:
    explicit GalvoTwin(const GalvoTruth& truth) : truth_(truth) {}
    void home() override {}
    bool homed() const override { return true; }
    Vec3 position_after_homing_mm() const override { return {0, 0, 0}; }
    Vec3 actual_position_mm(const Vec3& commanded) const override;
    std::optional<std::vector<std::string>> settings_command(const gcode::Line& line) override;
    const GalvoTruth& truth() const { return truth_; }

  private:
    GalvoTruth truth_;
};

// How well intended positions are marked, in the twin's truth: each intended point is sent as
// `command_for(point)` (identity before a correction, the correction after), and the marks land
// where the field puts them. Rotation and translation are taken out (the camera's frame has no
// preferred origin or heading); scale, skew and every distortion stay in.
using GalvoJudgement = PlacedJudgement;
GalvoJudgement judge_galvo(const GalvoTruth& truth, const std::vector<Vec2>& intended_mm,
                           const std::function<Vec2(Vec2)>& command_for);

// A fresh grid of `count` x `count` marks over `area_mm` (min x, min y, max x, max y), each in the
// middle of its cell: half a cell off any grid with nodes on the area's edges.
std::vector<Vec2> fresh_grid(const std::array<double, 4>& area_mm, int count);
// The area a judgement without a table covers: the field less a pitch of the 31-mark grid on
// each side.
std::array<double, 4> field_less_a_pitch(const GalvoTruth& truth);

// What goes wrong when a grid is burned: marks that misfire (their strokes dropped) and spatter
// (small round blobs thrown near the marks).
struct BurnFaults {
    std::vector<Vec2> misfires_at_mm;  // drop the strokes of the mark commanded here
    double misfire_radius_mm = 1.0;
    std::vector<Vec2> spatter_at_mm;  // a blob here (true position)
    double spatter_radius_mm = 0.25;
};
std::vector<StrokeSegment> with_burn_faults(const std::vector<Stroke>& burned,
                                            const BurnFaults& faults);

}  // namespace calbox::sim
