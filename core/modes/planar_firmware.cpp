// The planar mode's firmware settings: what of the error model a machine's own scale and skew
// settings can carry, each line with what it leaves uncorrected.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/geometry/placement.hpp"
#include "core/models/klipper_config.hpp"
#include "core/modes/planar.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {

using geometry::Point2;

namespace {

// The settings in the firmware's own words: x and y scaled by `sx`, `sy` (an axis that travels
// (1 + s) too far needs 1 / (1 + s) of its steps per mm), x leaning `skew` mm per mm of y.
void firmware_lines(std::vector<std::string>& out, const models::MachineFile& machine,
                    const PlanarSolution& s, double sx, double sy, double skew) {
    const double fx = 1 / (1 + sx), fy = 1 / (1 + sy);
    const auto& planar = *machine.planar;
    const bool steps = planar.steps_per_mm_x && planar.steps_per_mm_y;
    const std::string factors = "multiply X steps/mm by " + number_text("%.6f", fx) + " and Y by " +
                                number_text("%.6f", fy);
    if (machine.firmware == "marlin") {
        out.emplace_back(steps ? "M92 X" + number_text("%.4f", *planar.steps_per_mm_x * fx) + " Y" +
                                     number_text("%.4f", *planar.steps_per_mm_y * fy)
                               : "; M92: " + factors);
        // Marlin's skew correction moves x by -y * I: I is the lean measured.
        out.emplace_back("M852 I" + number_text("%.6f", skew));
        if (s.backlash_mm)
            out.emplace_back("M425 X" + number_text("%.3f", std::max(0.0, s.backlash_mm->x)) +
                             " Y" + number_text("%.3f", std::max(0.0, s.backlash_mm->y)));
        out.emplace_back("M500");
    } else if (machine.firmware == "grbl") {
        if (steps) {
            out.emplace_back("$100=" + number_text("%.4f", *planar.steps_per_mm_x * fx));
            out.emplace_back("$101=" + number_text("%.4f", *planar.steps_per_mm_y * fy));
        } else {
            out.emplace_back("; $100, $101: " + factors);
        }
        out.emplace_back("; grbl has no skew setting: use the compensated G-code for squareness");
    } else if (machine.firmware == "klipper") {
        out.emplace_back("; [stepper_x] rotation_distance: multiply by " +
                         number_text("%.6f", 1 + sx) + ", [stepper_y] by " +
                         number_text("%.6f", 1 + sy));
        // The printer's own skew profile measured none: the lean is the one to save.
        for (auto& line : models::klipper_skew_commands(
                 *models::klipper_cartesian_corrected({1, 1, std::nullopt, true}, sx, sy, skew)
                      .xy_skew))
            out.push_back(std::move(line));
        out.emplace_back("SAVE_CONFIG");
    } else if (machine.firmware == "linuxcnc") {
        out.emplace_back(
            "; [JOINT_0] COMP_FILE (COMP_FILE_TYPE = 0: nominal actual), and the same "
            "for [JOINT_1] with y:");
        for (const double x : {s.min_x_mm, 0.5 * (s.min_x_mm + s.max_x_mm), s.max_x_mm})
            out.emplace_back("; " + number_text("%.3f", x) + " " +
                             number_text("%.4f", x * (1 + sx)));
        if (s.backlash_mm) {
            out.emplace_back("; [JOINT_0] BACKLASH = " +
                             number_text("%.3f", std::max(0.0, s.backlash_mm->x)));
            out.emplace_back("; [JOINT_1] BACKLASH = " +
                             number_text("%.3f", std::max(0.0, s.backlash_mm->y)));
        }
        out.emplace_back(
            "; linuxcnc has no skew setting: use the compensated G-code for squareness");
    } else {
        out.emplace_back("; " + machine.firmware + ": " + factors);
    }
}

}  // namespace

FirmwareSettings planar_firmware_settings(const models::MachineFile& machine,
                                          const PlanarSolution& s) {
    // Scale and skew settings can carry the field's linear part over the area only: the best
    // affine fit of e over the measured holes, its rotation left to the work's heading.
    // e ~ (a x + b y + tx, c x + d y + ty); turned by -c it is (a x + (b + c) y, d y): x scale a,
    // y scale d, and x moving (b + c) per mm of y.
    Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> right = Eigen::Matrix<double, 6, 1>::Zero();
    std::vector<Point2> field;
    for (std::size_t i = 0; i < s.commanded_mm.size(); ++i) {
        const Point2 c = s.commanded_mm[i];
        const Point2 e = models::planar_error_mm(s.fit.parameters, c, s.tool_length_mm);
        field.push_back({e.x + s.fit.residuals_mm[i].x, e.y + s.fit.residuals_mm[i].y});
        Eigen::Matrix<double, 6, 1> rx, ry;
        rx << c.x, c.y, 0, 0, 1, 0;
        ry << 0, 0, c.x, c.y, 0, 1;
        normal += rx * rx.transpose() + ry * ry.transpose();
        right += rx * field.back().x + ry * field.back().y;
    }
    const Eigen::Matrix<double, 6, 1> affine = normal.ldlt().solve(right);
    const double sx = affine(0), sy = affine(3), skew = affine(1) + affine(2);
    FirmwareSettings f;
    f.scale_x = sx, f.scale_y = sy, f.skew = skew;
    // What they leave: the field less its linear part, the placement out.
    std::vector<Point2> left, commanded_plus;
    for (std::size_t i = 0; i < field.size(); ++i) {
        const Point2 c = s.commanded_mm[i];
        left.push_back({field[i].x - sx * c.x - skew * c.y, field[i].y - sy * c.y});
        commanded_plus.push_back({c.x + left.back().x, c.y + left.back().y});
    }
    std::vector<Point2> placed_left;
    const auto placement = geometry::best_rigid_placement(commanded_plus, s.commanded_mm);
    for (std::size_t i = 0; i < left.size(); ++i) {
        const Point2 p = placement.apply(commanded_plus[i]);
        placed_left.push_back({p.x - s.commanded_mm[i].x, p.y - s.commanded_mm[i].y});
    }
    f.mean_left_mm = models::norm_statistics(placed_left).mean_mm;
    f.mean_before_mm = s.before.mean_mm;
    auto& out = f.lines;
    out.emplace_back("; calbox planar, the best linear fit over the holes: x travels " +
                     number_text("%+.4f", 100 * sx) + " %, y " + number_text("%+.4f", 100 * sy) +
                     " %, the axes are " + number_text("%+.4f", skew * 1000) +
                     " mrad out of square (x moves " + number_text("%+.6f", skew) +
                     " mm per mm of y)");
    if (s.backlash_mm)
        out.emplace_back("; backlash " + number_text("%.3f", s.backlash_mm->x) + " mm in x, " +
                         number_text("%.3f", s.backlash_mm->y) +
                         " mm in y (the hole drilled from the other side): jobs that approach "
                         "their features from one side do not see it");
    out.emplace_back("; these settings leave " + number_text("%.3f", f.mean_left_mm) +
                     " mm mean error norm of " + number_text("%.3f", f.mean_before_mm) +
                     " (straightness, yaw and what the model does not hold); the compensated "
                     "G-code corrects all of the model");
    firmware_lines(out, machine, s, sx, sy, skew);
    return f;
}

}  // namespace calbox::modes
