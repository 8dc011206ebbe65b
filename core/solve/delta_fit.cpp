#include "core/solve/delta_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numbers>

#include "core/geometry/placement.hpp"
#include "core/number_text.hpp"

namespace calbox::solve {
using geometry::best_rigid_placement;
using geometry::RigidPlacement;
namespace {

using models::DeltaGeometry;

// The geometry parameters, in gauge: rod, two rod trims (the third is minus their sum), radius,
// two angle trims (likewise), two endstop offsets relative to tower C's, height. `step` changes
// positions by about a tenth of a millimetre (columns of comparable size); beyond
// `useful_uncertainty` (in the parameter's unit) a correction cannot use the estimate and the
// parameter is held at the firmware's value.
struct ParameterSpec {
    const char* name;
    double step;
    double useful_uncertainty;
};
constexpr int kGeometry = 9;
constexpr int kHeight = 8;
static_assert(kGeometry == static_cast<int>(kDeltaParameterCount));
constexpr std::array<ParameterSpec, kGeometry> kParameters{{
    {"diagonal_rod_mm", 0.1, 0.2},
    {"diagonal_rod_trim_mm[A]", 0.1, 0.2},
    {"diagonal_rod_trim_mm[B]", 0.1, 0.2},
    {"radius_mm", 0.1, 0.2},
    {"tower_angle_trim_deg[A]", 0.05, 0.1},
    {"tower_angle_trim_deg[B]", 0.05, 0.1},
    {"endstop_offset_mm[A]", 0.1, 0.2},
    {"endstop_offset_mm[B]", 0.1, 0.2},
    {"height_mm", 0.1, 0.2},
}};

using Vector = Eigen::VectorXd;

Vector pack(const DeltaGeometry& g0) {
    const DeltaGeometry g = models::in_gauge(g0);
    Vector v(kGeometry);
    v << g.diagonal_rod_mm, g.diagonal_rod_trim_mm[0], g.diagonal_rod_trim_mm[1], g.radius_mm,
        g.tower_angle_trim_deg[0], g.tower_angle_trim_deg[1],
        g.endstop_offset_mm[0] - g.endstop_offset_mm[2],
        g.endstop_offset_mm[1] - g.endstop_offset_mm[2], g.height_mm;
    return v;
}

DeltaGeometry unpack(const Vector& v) {
    DeltaGeometry g;
    g.diagonal_rod_mm = v[0];
    g.diagonal_rod_trim_mm = {v[1], v[2], -v[1] - v[2]};
    g.radius_mm = v[3];
    g.tower_angle_trim_deg = {v[4], v[5], -v[4] - v[5]};
    g.endstop_offset_mm = {v[6], v[7], 0.0};
    g.height_mm = v[8];
    return models::in_gauge(g);
}

// Levenberg-Marquardt on r(x) with a numerical Jacobian; `free` marks the parameters it moves.
struct Solution {
    Vector x;
    Eigen::MatrixXd jacobian;  // at the solution, free columns only
    double cost = 0;
    FitConvergence convergence;
};

// r(x), where a geometry that cannot reach a commanded point is the fit's error, not the
// kinematics': the measurements are then far from anything this machine's model can be.
Vector residuals_at(const std::function<Vector(const Vector&)>& r, const Vector& x,
                    const char* where) {
    try {
        return r(x);
    } catch (const models::UnreachableError& e) {
        throw FitError(std::string("the fit cannot go on: ") + where + ", " + e.what() +
                       " (the measurements are far from what this machine's model can give)");
    }
}

Eigen::MatrixXd jacobian_of(const std::function<Vector(const Vector&)>& r, const Vector& x,
                            const std::vector<int>& free, const std::vector<double>& step) {
    const Vector r0 = residuals_at(r, x, "at the current estimate");
    Eigen::MatrixXd j(r0.size(), static_cast<Eigen::Index>(free.size()));
    for (std::size_t k = 0; k < free.size(); ++k) {
        Vector up = x, down = x;
        const double h = step[static_cast<std::size_t>(free[k])] * 1e-3;
        up[free[k]] += h;
        down[free[k]] -= h;
        j.col(static_cast<Eigen::Index>(k)) =
            (residuals_at(r, up, "a parameter nudged for the Jacobian") -
             residuals_at(r, down, "a parameter nudged for the Jacobian")) /
            (2 * h);
    }
    return j;
}

Solution levenberg_marquardt(const std::function<Vector(const Vector&)>& r, Vector x,
                             const std::vector<int>& free, const std::vector<double>& step) {
    // Converged when a step lowers the sum of squares by less than this share of it: the
    // parameters then move by nanometres, far below any uncertainty.
    constexpr double kConvergedGain = 1e-14;
    constexpr int kMaxIterations = 100;
    constexpr int kMaxDampingTries = 10;  // lambda grows 10^10 fold: no descent left
    double lambda = 1e-3;
    Vector res = residuals_at(r, x, "at the starting geometry");
    double cost = res.squaredNorm();
    FitConvergence c;
    c.stopped_on = "the iteration limit";
    c.stopped_on_limit = true;
    while (c.iterations < kMaxIterations) {
        ++c.iterations;
        const Eigen::MatrixXd j = jacobian_of(r, x, free, step);
        const Eigen::MatrixXd jtj = j.transpose() * j;
        const Vector g = j.transpose() * res;
        bool improved = false, converged = false;
        for (int tries = 0; tries < kMaxDampingTries && !improved; ++tries) {
            Eigen::MatrixXd a = jtj;
            a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
            const Vector dx = a.ldlt().solve(-g);
            Vector candidate = x;
            for (std::size_t k = 0; k < free.size(); ++k)
                candidate[free[k]] += dx[static_cast<Eigen::Index>(k)];
            Vector candidate_res;
            try {
                candidate_res = r(candidate);
            } catch (const models::UnreachableError&) {
                lambda *= 10;  // a trial step too far: a shorter one may not be
                continue;
            }
            const double candidate_cost = candidate_res.squaredNorm();
            if (candidate_cost < cost) {
                const double gain = cost - candidate_cost;
                c.final_step = 0;
                for (std::size_t k = 0; k < free.size(); ++k) {
                    c.final_step =
                        std::max(c.final_step, std::abs(dx[static_cast<Eigen::Index>(k)]) /
                                                   step[static_cast<std::size_t>(free[k])]);
                }
                x = candidate;
                res = candidate_res;
                cost = candidate_cost;
                lambda = std::max(lambda / 10, 1e-12);
                improved = true;
                converged = gain < kConvergedGain * (1 + cost);
            } else {
                lambda *= 10;
            }
        }
        if (!improved || converged) {
            c.stopped_on = improved ? "a step that no longer lowers the residual"
                                    : "no step that lowers the residual";
            c.stopped_on_limit = false;
            break;
        }
    }
    return {x, jacobian_of(r, x, free, step), cost, c};
}

// Bed points for judging a correction: rings over the printable area.
std::vector<geometry::Point3> judging_points(double radius_mm, double z_mm) {
    std::vector<geometry::Point3> out{{0, 0, z_mm}};
    for (int ring = 1; ring <= 6; ++ring) {
        const double r = radius_mm * ring / 6;
        const int n = 6 * ring;
        for (int k = 0; k < n; ++k)
            out.push_back({r * std::cos(2 * std::numbers::pi * k / n),
                           r * std::sin(2 * std::numbers::pi * k / n), z_mm});
    }
    return out;
}

}  // namespace

namespace {

void check_inputs(const models::MachineFile& machine,
                  const std::vector<FeatureMeasurement>& features,
                  const std::vector<ProbePoint>& probe) {
    if (!machine.delta) throw FitError("the machine file has no [delta] table");
    constexpr std::size_t kMinimumFeatures = 12;
    if (features.size() < kMinimumFeatures) {
        throw FitError("too few features: " + std::to_string(features.size()) +
                       ", the fit needs at least " + std::to_string(kMinimumFeatures) +
                       " spread over the bed");
    }
    for (const auto& f : features) {
        const auto finite = [](double v) { return std::isfinite(v); };
        if (!finite(f.commanded_mm.x) || !finite(f.commanded_mm.y) || !finite(f.commanded_mm.z) ||
            !finite(f.measured_mm.x) || !finite(f.measured_mm.y) || !(f.sigma_mm > 0)) {
            throw FitError("feature " + f.id +
                           " has a missing or non-finite position or uncertainty");
        }
        if (std::hypot(f.commanded_mm.x, f.commanded_mm.y) > machine.bed_radius_mm) {
            throw FitError("feature " + f.id + " was commanded off the bed (" +
                           std::to_string(std::hypot(f.commanded_mm.x, f.commanded_mm.y)) +
                           " mm from the centre, bed radius " +
                           std::to_string(machine.bed_radius_mm) + " mm)");
        }
    }
    for (const auto& p : probe) {
        if (!std::isfinite(p.x_mm) || !std::isfinite(p.y_mm) || !std::isfinite(p.z_mm) ||
            !(p.sigma_mm > 0)) {
            throw FitError("a probe point is not finite");
        }
        if (std::hypot(p.x_mm, p.y_mm) > machine.bed_radius_mm)
            throw FitError("a probe point lies off the bed");
    }
}

std::vector<double> parameter_steps() {
    std::vector<double> step;
    step.reserve(kParameters.size());
    for (const auto& p : kParameters) step.push_back(p.step);
    return step;
}

// Commanded carried onto measured, rigidly: the placement's first guess.
RigidPlacement rigid_placement_of(const std::vector<FeatureMeasurement>& features) {
    std::vector<geometry::Point2> commanded, measured;
    for (const auto& f : features)
        commanded.push_back({f.commanded_mm.x, f.commanded_mm.y}),
            measured.push_back(f.measured_mm);
    return best_rigid_placement(commanded, measured);
}

// The fit, again without the geometry parameter worst determined for as long as one is known
// worse than is useful (`free` loses it): the solution and its covariance over `free`.
std::pair<Solution, Eigen::MatrixXd> fit_holding_unseen(
    const std::function<Vector(const Vector&)>& residuals, const Vector& x0, std::vector<int>& free,
    const std::vector<double>& step) {
    Solution solution;
    Eigen::MatrixXd covariance;
    while (true) {
        solution = levenberg_marquardt(residuals, x0, free, step);
        covariance = (solution.jacobian.transpose() * solution.jacobian)
                         .completeOrthogonalDecomposition()
                         .pseudoInverse();
        int worst = -1;
        double worst_ratio = 1;
        for (std::size_t k = 0; k < free.size(); ++k) {
            if (free[k] >= kGeometry) continue;  // the placement is never held
            const auto kk = static_cast<Eigen::Index>(k);
            const double ratio = std::sqrt(std::max(0.0, covariance(kk, kk))) /
                                 kParameters[static_cast<std::size_t>(free[k])].useful_uncertainty;
            if (ratio > worst_ratio) worst_ratio = ratio, worst = static_cast<int>(k);
        }
        if (worst < 0) break;
        free.erase(free.begin() + worst);
    }
    return {solution, covariance};
}

// Observability: singular values of the Jacobian with columns scaled to comparable steps.
void observability(const Eigen::MatrixXd& jacobian, const std::vector<int>& free,
                   const std::vector<double>& step, DeltaEstimate& result) {
    Eigen::MatrixXd scaled = jacobian;
    for (std::size_t k = 0; k < free.size(); ++k)
        scaled.col(static_cast<Eigen::Index>(k)) *= step[static_cast<std::size_t>(free[k])];
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled);
    const Vector& sv = svd.singularValues();
    for (Eigen::Index i = 0; i < sv.size(); ++i) result.singular_values.push_back(sv[i]);
    result.condition_number =
        sv[sv.size() - 1] > 0 ? sv[0] / sv[sv.size() - 1] : std::numeric_limits<double>::infinity();
}

// Each geometry parameter's uncertainty and their covariance (widened by `widen`); a parameter
// the fit held is marked so.
void keep_uncertainties(const std::vector<int>& free, const Eigen::MatrixXd& covariance,
                        double widen, DeltaEstimate& result) {
    result.covariance.assign(std::size_t{kGeometry} * kGeometry, 0.0);
    for (int i = 0; i < kGeometry; ++i) {
        const auto it = std::find(free.begin(), free.end(), i);
        const bool held = it == free.end();
        result.held[static_cast<std::size_t>(i)] = held;
        if (held) continue;
        const auto k = static_cast<Eigen::Index>(it - free.begin());
        result.uncertainty[static_cast<std::size_t>(i)] =
            std::sqrt(std::max(0.0, covariance(k, k)));
        for (int j = 0; j < kGeometry; ++j) {
            const auto other = std::find(free.begin(), free.end(), j);
            if (other == free.end()) continue;
            result
                .covariance[static_cast<std::size_t>(i) * kGeometry + static_cast<std::size_t>(j)] =
                widen * covariance(k, static_cast<Eigen::Index>(other - free.begin()));
        }
    }
}

// The estimate off by its own uncertainty: each judging point's XY moves by J dx for a
// parameter error dx, whose spread is J C J^T (C the estimate's `covariance`); none without one.
std::vector<double> xy_spread(const std::vector<geometry::Point3>& judge,
                              const DeltaGeometry& estimate, const DeltaGeometry& after,
                              const std::vector<double>& covariance) {
    std::vector<double> spread(judge.size(), 0.0);
    if (covariance.size() != std::size_t{kGeometry} * kGeometry) return spread;
    const Vector base = pack(estimate);
    const std::vector<double> steps = parameter_steps();
    // Per parameter, how each point's XY moves per unit of it.
    std::vector<std::vector<geometry::Point2>> moves(kGeometry);
    for (int k = 0; k < kGeometry; ++k) {
        const double h = 1e-3 * steps[static_cast<std::size_t>(k)];
        Vector moved = base;
        moved[k] += h;
        const DeltaGeometry g = unpack(moved);
        auto& move = moves[static_cast<std::size_t>(k)];
        for (std::size_t i = 0; i < judge.size(); ++i) {
            const auto p = models::actual_position_mm(g, after, judge[i]);
            const auto q = models::actual_position_mm(estimate, after, judge[i]);
            move.push_back({(p.x - q.x) / h, (p.y - q.y) / h});
        }
        // A turn or shift of the whole print is where it lies on the bed, not an error (the
        // fit cannot see it either): each parameter's move field loses its rigid part, the
        // best placement of the points moved a micrometre's worth along it taken out.
        constexpr double kAlong = 1e-3;
        std::vector<geometry::Point2> from, to;
        for (std::size_t i = 0; i < judge.size(); ++i) {
            from.push_back({judge[i].x, judge[i].y});
            to.push_back({judge[i].x + kAlong * move[i].x, judge[i].y + kAlong * move[i].y});
        }
        const auto placed = best_rigid_placement(from, to);
        for (std::size_t i = 0; i < judge.size(); ++i) {
            const auto at = placed.apply(from[i]);
            move[i] = {(to[i].x - at.x) / kAlong, (to[i].y - at.y) / kAlong};
        }
    }
    for (std::size_t i = 0; i < judge.size(); ++i)
        for (int k = 0; k < kGeometry; ++k)
            for (int l = 0; l < kGeometry; ++l) {
                const double c = covariance[static_cast<std::size_t>(k) * kGeometry +
                                            static_cast<std::size_t>(l)];
                if (c == 0) continue;
                const auto& a = moves[static_cast<std::size_t>(k)][i];
                const auto& b = moves[static_cast<std::size_t>(l)][i];
                spread[i] += c * (a.x * b.x + a.y * b.y);
            }
    return spread;
}

}  // namespace

DeltaEstimate estimate_delta_geometry(const models::MachineFile& machine,
                                      const std::vector<FeatureMeasurement>& features,
                                      const std::vector<ProbePoint>& probe) {
    check_inputs(machine, features, probe);
    const DeltaGeometry firmware = *machine.delta;
    DeltaEstimate result;
    result.used_probe = probe.size() >= 3;
    result.before = models::in_gauge(firmware);
    result.expected_rms_mm = features.front().sigma_mm;

    // Unknowns: geometry, then placement (rotation, x, y).
    const Vector fw = pack(firmware);
    Vector x0(kGeometry + 3);
    x0 << fw, 0, 0, 0;
    std::vector<double> step = parameter_steps();
    step.insert(step.end(), {0.01, 0.1, 0.1});
    // First guess of the placement: commanded carried onto measured, rigidly.
    const RigidPlacement guess = rigid_placement_of(features);
    x0[kGeometry] = guess.angle_rad;
    x0[kGeometry + 1] = guess.translation_mm.x;
    x0[kGeometry + 2] = guess.translation_mm.y;
    // Without heights the height is not measured; it is the one that puts the nozzle on the bed
    // at the centre when commanded to z = 0, as the paper test every delta owner does left it.
    const auto geometry_of = [&](const Vector& x) {
        DeltaGeometry g = unpack(x.head(kGeometry));
        if (!result.used_probe) g.height_mm -= models::actual_position_mm(g, firmware, {0, 0, 0}).z;
        return g;
    };
    const auto residuals = [&](const Vector& x) {
        const DeltaGeometry g = geometry_of(x);
        const double c = std::cos(x[kGeometry]), s = std::sin(x[kGeometry]);
        Vector r(static_cast<Eigen::Index>(2 * features.size() + probe.size()));
        Eigen::Index k = 0;
        for (const auto& f : features) {
            const auto p = models::actual_position_mm(g, firmware, f.commanded_mm);
            // Seen on its ray at the mapping height, the point lies where the ray meets its own
            // (predicted) height: measured = placed position - (height - mapping height) * shift.
            const double dz = f.height_measured ? 0.0 : p.z - f.seen_at_height_mm;
            r[k++] = (c * p.x - s * p.y + x[kGeometry + 1] - dz * f.shift_per_height.x -
                      f.measured_mm.x) /
                     f.sigma_mm;
            r[k++] = (s * p.x + c * p.y + x[kGeometry + 2] - dz * f.shift_per_height.y -
                      f.measured_mm.y) /
                     f.sigma_mm;
        }
        for (const auto& p : probe)
            r[k++] = (models::actual_position_mm(g, firmware, {p.x_mm, p.y_mm, 0}).z - p.z_mm) /
                     p.sigma_mm;
        return r;
    };
    // What the camera cannot see: without heights, the height (a common carriage shift moves the
    // nozzle straight down) is held.
    std::vector<int> free;
    for (int i = 0; i < kGeometry + 3; ++i)
        if (i != kHeight || result.used_probe) free.push_back(i);
    const auto [solution, covariance] = fit_holding_unseen(residuals, x0, free, step);
    observability(solution.jacobian, free, step, result);
    // The features' normalised residual in the first feature's units. Heights (a probe's, or the
    // strands') are left out: the fit meets them closely whatever the camera's lens model says,
    // and counted in they would hide a wrong one's XY misfit.
    const auto feature_rows = static_cast<Eigen::Index>(2 * features.size());
    result.fit_rms_mm =
        std::sqrt(
            residuals_at(residuals, solution.x, "the final fit").head(feature_rows).squaredNorm() /
            static_cast<double>(feature_rows)) *
        result.expected_rms_mm;
    result.estimate = geometry_of(solution.x);
    result.convergence = solution.convergence;
    result.placement = {solution.x[kGeometry],
                        {solution.x[kGeometry + 1], solution.x[kGeometry + 2]}};
    // Features scattering more than their uncertainties say (a lens model short of the real one)
    // widen the covariance by the ratio; never narrow it.
    const double widen =
        result.expected_rms_mm > 0
            ? std::pow(std::max(1.0, result.fit_rms_mm / result.expected_rms_mm), 2)
            : 1.0;
    keep_uncertainties(free, covariance, widen, result);
    return result;
}

DeltaCorrection design_delta_correction(const models::MachineFile& machine,
                                        const DeltaEstimate& fitted) {
    if (!machine.delta) throw FitError("the machine file has no [delta] table");
    const DeltaGeometry firmware = *machine.delta;
    // With heights, make XY and the bed right. Without them, a bed the fit finds out of level by
    // more than the camera's height resolution is made level too (its centre stays where the
    // printer's zeroing put it); a bed already level within that is kept as the printer has it,
    // so that a probe's levelling is not spoiled by a camera's estimate.
    DeltaCorrection result;
    const auto judge = judging_points(machine.bed_radius_mm * 0.95, 0.0);
    const DeltaGeometry estimate = fitted.estimate;
    std::vector<double> z_now;
    z_now.reserve(judge.size());
    for (const auto& p : judge)
        z_now.push_back(models::actual_position_mm(estimate, firmware, p).z);
    const auto [lowest, highest] = std::minmax_element(z_now.begin(), z_now.end());
    result.predicted_height_range_now_mm = *highest - *lowest;
    constexpr double kLevelEnoughMm = 0.1;
    result.levels_bed = fitted.used_probe || result.predicted_height_range_now_mm > kLevelEnoughMm;
    const auto correction_residuals = [&](const Vector& x) {
        const DeltaGeometry g = unpack(x);
        Vector r(static_cast<Eigen::Index>(3 * judge.size()));
        for (std::size_t i = 0; i < judge.size(); ++i) {
            const auto p = models::actual_position_mm(estimate, g, judge[i]);
            const auto k = static_cast<Eigen::Index>(3 * i);
            r[k] = p.x - judge[i].x;
            r[k + 1] = p.y - judge[i].y;
            // Keeping a levelled bed weighs more than the last micrometre of XY: a spoiled first
            // layer costs more than a trace of scale.
            r[k + 2] = result.levels_bed ? p.z - judge[i].z : 3 * (p.z - z_now[i]);
        }
        return r;
    };
    std::vector<int> all(kGeometry);
    for (int i = 0; i < kGeometry; ++i) all[static_cast<std::size_t>(i)] = i;
    const Solution correction =
        levenberg_marquardt(correction_residuals, pack(estimate), all, parameter_steps());
    result.after = unpack(correction.x);
    result.convergence = correction.convergence;
    double sum = 0, worst = 0, change = 0;
    std::vector<geometry::Point2> xy_now, xy_after;
    for (std::size_t i = 0; i < judge.size(); ++i) {
        const auto p = models::actual_position_mm(estimate, result.after, judge[i]);
        const auto now = models::actual_position_mm(estimate, firmware, judge[i]);
        const double e = std::hypot(p.x - judge[i].x, p.y - judge[i].y);
        sum += e * e;
        worst = std::max(worst, e);
        change = std::max(change, std::abs(p.z - z_now[i]));
        xy_now.push_back({now.x, now.y}), xy_after.push_back({p.x, p.y});
    }
    // A turn or shift of the whole print is no change of its shape (a tower angle trim turns
    // the frame): taken out before the largest move is read.
    const auto turn = best_rigid_placement(xy_now, xy_after);
    for (std::size_t i = 0; i < judge.size(); ++i) {
        const auto p = turn.apply(xy_now[i]);
        result.predicted_xy_change_mm = std::max(
            result.predicted_xy_change_mm, std::hypot(xy_after[i].x - p.x, xy_after[i].y - p.y));
    }
    const std::vector<double> spread = xy_spread(judge, estimate, result.after, fitted.covariance);
    double spread_sum = 0, spread_worst = 0;
    for (std::size_t i = 0; i < judge.size(); ++i) {
        spread_sum += std::max(0.0, spread[i]);
        spread_worst = std::max(spread_worst, std::sqrt(std::max(0.0, spread[i])));
    }
    const auto n = static_cast<double>(judge.size());
    result.predicted_xy_rms_mm = std::sqrt(sum / n + spread_sum / n);
    result.predicted_xy_max_mm = std::hypot(worst, spread_worst);
    result.predicted_height_change_mm = change;
    return result;
}

std::vector<ParameterReport> report_parameters(const DeltaEstimate& fitted,
                                               const models::DeltaGeometry& after) {
    const Vector before = pack(fitted.before), est = pack(fitted.estimate), sent = pack(after);
    std::vector<ParameterReport> out;
    for (int i = 0; i < kGeometry; ++i) {
        const auto k = static_cast<std::size_t>(i);
        ParameterReport p;
        p.name = kParameters[k].name;
        p.before = before[i];
        p.estimate = est[i];
        p.after = sent[i];
        p.held = fitted.held[k];
        p.uncertainty = fitted.uncertainty[k];
        out.push_back(p);
    }
    return out;
}

void check_residual(const DeltaEstimate& fitted, const DeltaFitLimits& limits) {
    if (fitted.fit_rms_mm > limits.max_residual_ratio * fitted.expected_rms_mm) {
        char why[200];
        std::snprintf(why, sizeof why,
                      "refused: the measurements do not fit a delta printer's geometry (%.3f mm "
                      "RMS left, %.3f mm expected)",
                      fitted.fit_rms_mm, fitted.expected_rms_mm);
        throw FitError(why);
    }
}

void check_correction_bounds(const models::DeltaGeometry& before,
                             const models::DeltaGeometry& after, const DeltaFitLimits& limits) {
    // A correction this large is a wrong measurement or a broken machine, not a trim.
    const double radius_change = std::abs(after.radius_mm - before.radius_mm) / before.radius_mm;
    if (radius_change > limits.max_radius_change_fraction) {
        throw FitError("refused: the radius would change by " +
                       std::to_string(100 * radius_change) + " %, over the limit of " +
                       std::to_string(100 * limits.max_radius_change_fraction) + " %");
    }
    const double rod_change =
        std::abs(after.diagonal_rod_mm - before.diagonal_rod_mm) / before.diagonal_rod_mm;
    if (rod_change > limits.max_rod_change_fraction) {
        throw FitError("refused: the rod length would change by " +
                       std::to_string(100 * rod_change) + " %, over the limit of " +
                       std::to_string(100 * limits.max_rod_change_fraction) + " %");
    }
    for (double a : after.tower_angle_trim_deg) {
        if (std::abs(a) > limits.max_angle_trim_deg) {
            throw FitError("refused: a tower angle trim of " + std::to_string(a) +
                           " degrees is over the limit of " +
                           std::to_string(limits.max_angle_trim_deg));
        }
    }
}

DeltaFitResult fit_delta(const models::MachineFile& machine,
                         const std::vector<FeatureMeasurement>& features,
                         const std::vector<ProbePoint>& probe, const DeltaFitLimits& limits) {
    DeltaFitResult result;
    result.fitted = estimate_delta_geometry(machine, features, probe);
    result.correction = design_delta_correction(machine, result.fitted);
    result.parameters = report_parameters(result.fitted, result.correction.after);
    check_residual(result.fitted, limits);
    check_correction_bounds(result.fitted.before, result.correction.after, limits);
    return result;
}

double classic_rod_length_mm(const DeltaGeometry& firmware,
                             const std::vector<BarMeasurement>& bars) {
    if (bars.empty()) throw FitError("the classic method needs bar lengths");
    const double d0 = firmware.diagonal_rod_mm, r = firmware.radius_mm;
    const double h_star = std::sqrt(d0 * d0 - r * r);
    double sum = 0;
    for (const auto& bar : bars) {
        // The paper's L for a commanded move L* from the centre, under a true rod d.
        const auto move = [&](double d, double commanded) {
            const double dh = std::sqrt(d0 * d0 - (r - commanded) * (r - commanded)) - h_star;
            const double inner = std::sqrt(d * d - r * r) + dh;
            return r - std::sqrt(std::max(0.0, d * d - inner * inner));
        };
        const auto measured = [&](double d) {
            return move(d, bar.commanded_to_mm) - move(d, bar.commanded_from_mm);
        };
        // The search reaches a fifth of the rod either way; a bar whose length no rod there
        // gives is refused rather than answered with an end of the search.
        double lo = d0 * 0.8, hi = d0 * 1.2;
        const double at_lo = measured(lo), at_hi = measured(hi);
        if (!std::isfinite(bar.measured_mm) || bar.measured_mm < std::min(at_lo, at_hi) ||
            bar.measured_mm > std::max(at_lo, at_hi)) {
            throw FitError(
                "the classic method: a bar measured " + number_text("%.3f", bar.measured_mm) +
                " mm (commanded from " + number_text("%.1f", bar.commanded_from_mm) + " to " +
                number_text("%.1f", bar.commanded_to_mm) + " mm) is not what any rod from " +
                number_text("%.1f", lo) + " to " + number_text("%.1f", hi) + " mm gives (" +
                number_text("%.3f", std::min(at_lo, at_hi)) + " to " +
                number_text("%.3f", std::max(at_lo, at_hi)) + " mm)");
        }
        const bool rising = at_hi > at_lo;
        for (int i = 0; i < 200; ++i) {
            const double mid = (lo + hi) / 2;
            if ((measured(mid) < bar.measured_mm) == rising)
                lo = mid;
            else
                hi = mid;
        }
        sum += (lo + hi) / 2;
    }
    return sum / static_cast<double>(bars.size());
}

std::vector<ProbePoint> strand_heights_as_probe(const std::vector<FeatureMeasurement>& features) {
    std::vector<ProbePoint> probe;
    for (const auto& f : features) {
        if (!f.height_measured || f.free_bead || f.scraped || !(f.height_sigma_mm > 0)) continue;
        probe.push_back({f.commanded_mm.x, f.commanded_mm.y, f.seen_at_height_mm - f.commanded_mm.z,
                         f.height_sigma_mm});
    }
    return probe;
}

}  // namespace calbox::solve
