#pragma once
// Fits a delta printer's geometry to where its features really landed (commanded vs measured
// bed positions), with the artifact's placement on the bed as nuisance parameters, in the
// gauges a camera imposes; then designs the correction to send.
#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/placement.hpp"
#include "core/geometry/types.hpp"
#include "core/models/delta.hpp"
#include "core/models/machine_file.hpp"

namespace calbox::solve {

class FitError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct FeatureMeasurement {
    std::string id;
    geometry::Point3 commanded_mm;  // machine frame, as the job commanded it
    geometry::Point2 measured_mm;   // bed frame, where it was seen
    double sigma_mm = 0.01;         // standard uncertainty of each measured coordinate
    // A camera measures along a ray: the point was mapped at `seen_at_height_mm`, and moves by
    // `shift_per_height` (bed mm per mm) for a surface higher than that. Zero: no parallax.
    double seen_at_height_mm = 0;
    geometry::Point2 shift_per_height;
    // True when the height it was mapped at was measured (a first-layer strand's height from
    // its width): the point already lies where the material is, and the fit moves it along its
    // ray no further. `sigma_mm` then holds that height's share (height_sigma_mm times the
    // shift). A free bead's top stands at its own diameter whatever the gap under it.
    bool height_measured = false;
    double height_sigma_mm = 0;
    bool free_bead = false;
    bool scraped = false;  // as wide as the nozzle's flat: its height only bounded
    // False when some photo's corner could not be refined past the detector's own: the point
    // is then a few tenths of a pixel rougher (said in the measurement's summary).
    bool refined = true;
};

// A probed height: the nozzle's height over the bed when commanded to (x, y, 0).
struct ProbePoint {
    double x_mm = 0, y_mm = 0, z_mm = 0;
    double sigma_mm = 0.01;
};

// The nozzle's gap a first layer's pressed strands measured (their height from their width, the
// commanded layer taken off), as probe points: a free bead's says only that the gap was larger,
// a scraped one's only that it was smaller.
std::vector<ProbePoint> strand_heights_as_probe(const std::vector<FeatureMeasurement>& features);

// One set of bounds for every correction the delta mode may send, whichever method made it.
// The bounds a correction must keep (the machine file's [limits]).
using DeltaFitLimits = models::DeltaLimits;

struct ParameterReport {
    std::string name;        // the [delta] key with its tower: "diagonal_rod_trim_mm[A]"
    double before = 0;       // the firmware's belief, in gauge
    double estimate = 0;     // the fitted true value, in gauge
    double after = 0;        // what is sent
    double uncertainty = 0;  // standard uncertainty of the estimate; 0 when held
    bool held = false;       // the data do not determine it
};

constexpr std::size_t kDeltaParameterCount = 9;

// How a least-squares fit ended: its iterations, its last accepted step (the largest over the
// parameters, each in units of the change that moves the features about 0.1 mm) and why it
// stopped; on the iteration limit the answer is not a converged one.
struct FitConvergence {
    int iterations = 0;
    double final_step = 0;
    std::string stopped_on;
    bool stopped_on_limit = false;
};

// Stage one: the printer's true geometry from where its features landed.
struct DeltaEstimate {
    models::DeltaGeometry before, estimate;  // in gauge
    // Per parameter, in the order of the report: standard uncertainty (0 when held) and whether
    // the data left it undetermined (held at the firmware's value).
    std::array<double, kDeltaParameterCount> uncertainty{};
    std::array<bool, kDeltaParameterCount> held{};
    // The estimate's covariance in the fit's own parameters (the report's order), row by row,
    // scaled up where the features scatter more than their uncertainties say; a held
    // parameter's row and column are zero. Empty for an estimate read back from a record.
    std::vector<double> covariance;
    std::vector<double> singular_values;  // of the weighted, scaled Jacobian
    double condition_number = 0;
    double fit_rms_mm = 0;               // measured vs fitted, after the placement
    double expected_rms_mm = 0;          // what the measurements' own uncertainty leads to expect
    geometry::RigidPlacement placement;  // the artifact on the bed: machine frame -> bed frame
    bool used_probe = false;
    FitConvergence convergence;  // of the final fit (after undetermined parameters are held)
};

// Stage two: the parameters to send, and what the fit predicts they leave.
struct DeltaCorrection {
    models::DeltaGeometry after;  // in gauge
    // Over the printable area after the correction, one standard uncertainty: where the estimate
    // is off by its own covariance, the correction puts the nozzle off by this much (and by what
    // the correction's design leaves, in quadrature). Zero for an estimate without a covariance.
    double predicted_xy_rms_mm = 0, predicted_xy_max_mm = 0;
    double predicted_height_change_mm = 0;  // largest change of the height map, after vs now
    double predicted_xy_change_mm = 0;      // largest XY move it makes, a turn or shift taken out
    double predicted_height_range_now_mm = 0;  // the bed's height range the fit sees now
    bool levels_bed = false;  // the correction levels the bed (else keeps its height map)
    FitConvergence convergence;
};

struct DeltaFitResult {
    DeltaEstimate fitted;
    DeltaCorrection correction;
    std::vector<ParameterReport> parameters;
};

// Throws FitError for too few or bad points (NaN, off the bed); never refuses a large change.
DeltaEstimate estimate_delta_geometry(const models::MachineFile& machine,
                                      const std::vector<FeatureMeasurement>& features,
                                      const std::vector<ProbePoint>& probe);
DeltaCorrection design_delta_correction(const models::MachineFile& machine,
                                        const DeltaEstimate& fitted);
std::vector<ParameterReport> report_parameters(const DeltaEstimate& fitted,
                                               const models::DeltaGeometry& after);
// Each throws FitError("refused: ...") naming the bound that was passed.
void check_residual(const DeltaEstimate& fitted, const DeltaFitLimits& limits);
void check_correction_bounds(const models::DeltaGeometry& before,
                             const models::DeltaGeometry& after, const DeltaFitLimits& limits);

// The three stages and the checks: throws FitError for bad input, and for measurements the
// geometry cannot explain or a correction beyond the limits (nothing is returned to send).
DeltaFitResult fit_delta(const models::MachineFile& machine,
                         const std::vector<FeatureMeasurement>& features,
                         const std::vector<ProbePoint>& probe, const DeltaFitLimits& limits = {});

// The seed paper's closed-form rod correction (its equations 10-13), averaged over bars: each bar
// was commanded along a tower from `commanded_from_mm` (0: the centre, as in the paper) to
// `commanded_to_mm` from the centre, and measured `measured_mm` long. A bar that starts off the
// centre is the difference of two of the paper's moves.
struct BarMeasurement {
    double commanded_from_mm = 0;
    double commanded_to_mm = 0;
    double measured_mm = 0;
};
double classic_rod_length_mm(const models::DeltaGeometry& firmware,
                             const std::vector<BarMeasurement>& bars);

}  // namespace calbox::solve
