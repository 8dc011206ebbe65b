#pragma once
// The quasi-static error model of a gantry machine (router, cartesian printer, gantry laser)
// reduced to its working plane, after Kiridena and Ferreira: small errors of each link of the
// kinematic chain, the joints' errors polynomials in their own coordinate, composed to first
// order into the tool point's error e = U(x, y, h) p, linear in the parameters p.
//
// The chain: base -> Y axis (the gantry, travel y) -> X axis (the carriage on the gantry,
// travel x) -> the tool point, `abbe_height_mm` (the seed's X3) below the carriage's guides.
// A photo measures e in the plane only, and in a frame of its own: the machine's placement in
// that frame (a rotation and a translation) is fitted beside the parameters, and the parameters
// that the design cannot tell apart from others, or from the placement, are held at zero and
// reported with what absorbs them.
#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"

namespace calbox::models {

class PlanarModelError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

inline constexpr int kPlanarParameters = 12;

// Which small error of which link a parameter is, and the power of the joint coordinate it is
// multiplied by (an error polynomial's coefficient).
enum class ChainLink { y_axis, x_axis, tool };
enum class ErrorComponent { along_x, along_y, along_z, about_x, about_y, about_z };

struct PlanarParameterInfo {
    const char* name;         // in the user's words, as the result files spell it
    const char* unit;         // of the value (per mm, rad, rad/mm, 1/mm)
    const char* seed_symbol;  // the seed paper's symbol for the same error
    ChainLink link;
    ErrorComponent component;
    int power;  // of the link's joint coordinate (y for the y axis, x for the x axis)
};

// The twelve, in the order of the vectors below: x_scale, y_scale, xy_squareness,
// x_straightness, y_straightness, gantry_yaw_rate, x_pitch_rate, x_roll_rate, y_pitch_rate,
// y_roll_rate, tool_tilt_about_x, tool_tilt_about_y.
const std::array<PlanarParameterInfo, kPlanarParameters>& planar_parameters();

using PlanarVector = std::array<double, kPlanarParameters>;

// The two rows of U at a point (x and y of the error, per unit of each parameter), composed
// from each parameter's link, component and power: a translation error moves the tool point by
// itself; a rotation error turns everything after its link about the link's origin.
struct SensitivityRows {
    PlanarVector ex, ey;
};
SensitivityRows planar_sensitivity(geometry::Point2 at_mm, double abbe_height_mm);

// e(at) = U(at) p.
geometry::Point2 planar_error_mm(const PlanarVector& p, geometry::Point2 at_mm,
                                 double abbe_height_mm);

// A small rotation about the origin and a shift: the part of an error field that the work's
// zero and heading, set by hand on the machine, decide anyway.
struct SmallRigidMotion {
    double rotation_rad = 0;
    geometry::Point2 offset_mm;
    geometry::Point2 at(geometry::Point2 p) const {
        return {offset_mm.x - rotation_rad * p.y, offset_mm.y + rotation_rad * p.x};
    }
};
// The rigid part of e over a rectangle (least squares over a fine grid of it): a correction
// without it moves a job no further than its errors need.
SmallRigidMotion rigid_part_of(const PlanarVector& p, double abbe_height_mm, double min_x_mm,
                               double min_y_mm, double max_x_mm, double max_y_mm);

// Where to command so that the tool lands on `intended` moved by `rigid` (the part of the field
// left to the work's zero and heading): X_c = X_t' - e(X_c), the error taken at the compensated
// point (a fixed point; the error changes by under 1 % of itself over its own size, so a few
// iterations reach a nanometre).
geometry::Point2 planar_command_for(const PlanarVector& p, geometry::Point2 intended_mm,
                                    double abbe_height_mm, const SmallRigidMotion& rigid = {});

// The seed paper's planar form: e_x = A y^2 + B y + C x + D z, e_y = E x + F y + G z + H x y
// + I x^2, with z = X3.
struct SeedPlanarForm {
    double A = 0, B = 0, C = 0, D = 0, E = 0, F = 0, G = 0, H = 0, I = 0;
    geometry::Point2 error_mm(geometry::Point2 at_mm, double z) const;
};
// The parameters whose error field is the seed form's at height z (the chain's Abbe terms
// carry D and G, and B through the y axis's roll).
PlanarVector planar_from_seed_form(const SeedPlanarForm& form, double z);

// One measured point: where the tool was commanded, and where it was seen in the camera's frame.
struct PlanarObservation {
    geometry::Point2 commanded_mm;
    geometry::Point2 seen_mm;
    double sigma_mm = 0;  // standard uncertainty of each coordinate, 0: unknown
};

struct HeldParameter {
    int parameter = 0;
    std::string absorbed_by;  // the fitted terms whose columns span its column here
};

struct PlanarFit {
    PlanarVector parameters{};   // held ones are 0
    PlanarVector uncertainty{};  // standard uncertainty of each fitted one, 0 when held
    std::array<bool, kPlanarParameters> fitted{};
    std::vector<HeldParameter> held;
    double rotation_rad = 0;  // the machine's frame in the camera's (nuisance)
    geometry::Point2 translation_mm;
    int rank = 0;                // of [U | placement] over the design
    double condition = 0;        // of the fitted columns, each scaled to the design's span
    double residual_rms_mm = 0;  // per coordinate, after the fit
    // The a posteriori standard deviation of a coordinate over the a priori one (1 when the
    // measurements' uncertainties explain the residual).
    double unit_variance_ratio = 1;
    std::vector<geometry::Point2> residuals_mm;  // per observation, in the machine's frame
};

struct PlanarFitSettings {
    double abbe_height_mm = 0;
    // A column whose part outside the span of the columns chosen before it is under this fraction
    // of its length cannot be told apart from them.
    double separability = 1e-6;
    // Refuse a design whose fitted columns are this badly conditioned: the parameters would
    // amplify a micrometre of measurement noise into millimetres.
    double max_condition = 1e6;
};

// Least squares (Eigen) over at least twice as many coordinates as unknowns; throws
// PlanarModelError when there are too few points or the design is degenerate.
PlanarFit fit_planar_errors(const std::vector<PlanarObservation>& observations,
                            const PlanarFitSettings& settings);

// DETMAX (Mitchell): k of the candidate points that maximise det(A^T A) of the fitted columns
// and the placement: a random start of k - 3 points, grown to k by adding the point that raises
// the determinant most, then exchanges (add the best, drop the least useful) while they raise
// it. Deterministic for a seed. Returns indices into `candidates`.
std::vector<std::size_t> detmax_design(const std::vector<geometry::Point2>& candidates,
                                       std::size_t k, double abbe_height_mm, unsigned seed = 1);
// log det(A^T A) of a design, with the columns the candidates separate, coordinates in units of
// `span_mm` (so that designs over one universe compare).
double design_log_determinant(const std::vector<geometry::Point2>& points,
                              const std::vector<geometry::Point2>& candidates,
                              double abbe_height_mm);

// The seed paper's statistics of the error norm.
struct NormStatistics {
    double max_mm = 0, q3_mm = 0, median_mm = 0, q1_mm = 0, min_mm = 0, mean_mm = 0, std_mm = 0;
    std::size_t points = 0;
};
NormStatistics norm_statistics(const std::vector<geometry::Point2>& errors_mm);

}  // namespace calbox::models
