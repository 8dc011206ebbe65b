#include "core/models/planar_errors.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "core/geometry/placement.hpp"

namespace calbox::models {
namespace {

using geometry::Point2;

constexpr int kPlacementColumns = 3;  // rotation, then translation x and y
constexpr int kColumns = kPlacementColumns + kPlanarParameters;

// Where each link's frame sits in the machine's frame, and the tool point: the y axis's frame
// at (0, y), the x axis's at (x, y), the tool's at (x, y) with the tool point h below.
struct ChainPose {
    std::array<double, 3> origin[3];
    std::array<double, 3> tool;
};

ChainPose chain_pose(double x, double y, double h) {
    ChainPose c{};
    c.origin[static_cast<int>(ChainLink::y_axis)] = {0, y, 0};
    c.origin[static_cast<int>(ChainLink::x_axis)] = {x, y, 0};
    c.origin[static_cast<int>(ChainLink::tool)] = {x, y, 0};
    c.tool = {x, y, -h};
    return c;
}

// The homogeneous degree of a column in (x, y, h): what its value scales with when every
// length does.
int column_degree(int column) {
    if (column == 0) return 1;  // the placement's rotation
    if (column < kPlacementColumns) return 0;
    const auto& info = planar_parameters()[static_cast<std::size_t>(column - kPlacementColumns)];
    const bool rotation = info.component >= ErrorComponent::about_x;
    return info.power + (rotation ? 1 : 0);
}

// The design matrix's two rows for a point, every column (placement first), coordinates in
// units of `span`.
void design_rows(Point2 at, double h, double span, double* ex, double* ey) {
    const Point2 u{at.x / span, at.y / span};
    ex[0] = -u.y, ey[0] = u.x;
    ex[1] = 1, ey[1] = 0;
    ex[2] = 0, ey[2] = 1;
    const auto rows = planar_sensitivity(u, h / span);
    for (int j = 0; j < kPlanarParameters; ++j) {
        ex[kPlacementColumns + j] = rows.ex[static_cast<std::size_t>(j)];
        ey[kPlacementColumns + j] = rows.ey[static_cast<std::size_t>(j)];
    }
}

double span_of(const std::vector<Point2>& points) {
    double span = 0;
    for (const auto& p : points) span = std::max({span, std::abs(p.x), std::abs(p.y)});
    return span;
}

Eigen::MatrixXd full_design(const std::vector<Point2>& points, double h, double span) {
    Eigen::MatrixXd a(2 * static_cast<Eigen::Index>(points.size()), kColumns);
    std::array<double, kColumns> ex{}, ey{};
    for (std::size_t i = 0; i < points.size(); ++i) {
        design_rows(points[i], h, span, ex.data(), ey.data());
        for (int j = 0; j < kColumns; ++j) {
            a(2 * static_cast<Eigen::Index>(i), j) = ex[static_cast<std::size_t>(j)];
            a(2 * static_cast<Eigen::Index>(i) + 1, j) = ey[static_cast<std::size_t>(j)];
        }
    }
    return a;
}

const char* column_name(int column) {
    if (column == 0) return "the placement's rotation";
    if (column == 1) return "the placement's x";
    if (column == 2) return "the placement's y";
    return planar_parameters()[static_cast<std::size_t>(column - kPlacementColumns)].name;
}

struct ColumnChoice {
    std::vector<int> kept;  // placement columns always, then separable parameters in order
    std::vector<HeldParameter> held;
};

// Greedy in the parameters' order: a column is kept when enough of it lies outside the span of
// those kept before it; a held one is reported with the kept columns that make it up.
ColumnChoice choose_columns(const Eigen::MatrixXd& a, double separability) {
    ColumnChoice choice;
    Eigen::MatrixXd basis(a.rows(), 0);
    for (int j = 0; j < kColumns; ++j) {
        const Eigen::VectorXd column = a.col(j);
        const double length = column.norm();
        Eigen::VectorXd rest = column;
        if (basis.cols() > 0) rest -= basis * (basis.transpose() * column);
        if (length > 0 && rest.norm() > separability * length) {
            basis.conservativeResize(Eigen::NoChange, basis.cols() + 1);
            basis.col(basis.cols() - 1) = rest / rest.norm();
            choice.kept.push_back(j);
            continue;
        }
        if (j < kPlacementColumns)
            throw PlanarModelError("the points do not fix the machine's placement in the photo");
        Eigen::MatrixXd kept(a.rows(), static_cast<Eigen::Index>(choice.kept.size()));
        for (std::size_t k = 0; k < choice.kept.size(); ++k)
            kept.col(static_cast<Eigen::Index>(k)) = a.col(choice.kept[k]);
        const Eigen::VectorXd coefficients = kept.colPivHouseholderQr().solve(column);
        HeldParameter held{j - kPlacementColumns, ""};
        for (std::size_t k = 0; k < choice.kept.size(); ++k) {
            const double share = std::abs(coefficients(static_cast<Eigen::Index>(k))) *
                                 a.col(choice.kept[k]).norm() / std::max(length, 1e-300);
            if (share < 1e-3) continue;
            if (!held.absorbed_by.empty()) held.absorbed_by += ", ";
            held.absorbed_by += column_name(choice.kept[k]);
        }
        if (held.absorbed_by.empty()) held.absorbed_by = "nothing (it has no effect here)";
        choice.held.push_back(held);
    }
    return choice;
}

Eigen::MatrixXd kept_columns(const Eigen::MatrixXd& a, const std::vector<int>& kept) {
    Eigen::MatrixXd out(a.rows(), static_cast<Eigen::Index>(kept.size()));
    for (std::size_t k = 0; k < kept.size(); ++k)
        out.col(static_cast<Eigen::Index>(k)) = a.col(kept[k]);
    return out;
}

}  // namespace

const std::array<PlanarParameterInfo, kPlanarParameters>& planar_parameters() {
    using C = ErrorComponent;
    using L = ChainLink;
    // A linear translation error along its own axis is a scale error; across it, the axis runs
    // out of square; a quadratic one across it bows the axis (straightness). Angular errors
    // growing with travel (pitch, roll, yaw rates) act over the lever to the tool point.
    static const std::array<PlanarParameterInfo, kPlanarParameters> table{{
        {"x_scale", "mm/mm", "rho11", L::x_axis, C::along_x, 1},
        {"y_scale", "mm/mm", "rho21", L::y_axis, C::along_y, 1},
        {"xy_squareness", "rad", "dg (x axis on the gantry)", L::x_axis, C::along_y, 1},
        {"x_straightness", "1/mm", "(da2 - c1 g11)", L::x_axis, C::along_y, 2},
        {"y_straightness", "1/mm", "(db2 + b1 g11)", L::y_axis, C::along_x, 2},
        {"gantry_yaw_rate", "rad/mm", "g21", L::y_axis, C::about_z, 1},
        {"x_pitch_rate", "rad/mm", "b11", L::x_axis, C::about_y, 1},
        {"x_roll_rate", "rad/mm", "a11", L::x_axis, C::about_x, 1},
        {"y_pitch_rate", "rad/mm", "a21", L::y_axis, C::about_x, 1},
        {"y_roll_rate", "rad/mm", "b21", L::y_axis, C::about_y, 1},
        {"tool_tilt_about_x", "rad", "da4", L::tool, C::about_x, 0},
        {"tool_tilt_about_y", "rad", "db4", L::tool, C::about_y, 0},
    }};
    return table;
}

SensitivityRows planar_sensitivity(Point2 at_mm, double abbe_height_mm) {
    const ChainPose pose = chain_pose(at_mm.x, at_mm.y, abbe_height_mm);
    SensitivityRows rows{};
    const auto& table = planar_parameters();
    for (std::size_t j = 0; j < table.size(); ++j) {
        const auto& info = table[j];
        const double coordinate = info.link == ChainLink::y_axis   ? at_mm.y
                                  : info.link == ChainLink::x_axis ? at_mm.x
                                                                   : 1.0;
        const double weight = std::pow(coordinate, info.power);
        std::array<double, 3> move{0, 0, 0};
        const int c = static_cast<int>(info.component);
        if (c < 3) {
            move[static_cast<std::size_t>(c)] = weight;
        } else {
            // theta x (tool - origin), theta along one axis.
            const auto& o = pose.origin[static_cast<int>(info.link)];
            const std::array<double, 3> r{pose.tool[0] - o[0], pose.tool[1] - o[1],
                                          pose.tool[2] - o[2]};
            std::array<double, 3> theta{0, 0, 0};
            theta[static_cast<std::size_t>(c - 3)] = weight;
            move = {theta[1] * r[2] - theta[2] * r[1], theta[2] * r[0] - theta[0] * r[2],
                    theta[0] * r[1] - theta[1] * r[0]};
        }
        rows.ex[j] = move[0];
        rows.ey[j] = move[1];
    }
    return rows;
}

Point2 planar_error_mm(const PlanarVector& p, Point2 at_mm, double abbe_height_mm) {
    const auto rows = planar_sensitivity(at_mm, abbe_height_mm);
    Point2 e;
    for (std::size_t j = 0; j < p.size(); ++j) e.x += rows.ex[j] * p[j], e.y += rows.ey[j] * p[j];
    return e;
}

SmallRigidMotion rigid_part_of(const PlanarVector& p, double abbe_height_mm, double min_x_mm,
                               double min_y_mm, double max_x_mm, double max_y_mm) {
    // e ~ (tx - w y, ty + w x): three unknowns, linear.
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d right = Eigen::Vector3d::Zero();
    constexpr int kSteps = 20;
    for (int i = 0; i <= kSteps; ++i)
        for (int k = 0; k <= kSteps; ++k) {
            const Point2 at{min_x_mm + (max_x_mm - min_x_mm) * i / kSteps,
                            min_y_mm + (max_y_mm - min_y_mm) * k / kSteps};
            const Point2 e = planar_error_mm(p, at, abbe_height_mm);
            const Eigen::Vector3d rx{1, 0, -at.y}, ry{0, 1, at.x};
            normal += rx * rx.transpose() + ry * ry.transpose();
            right += rx * e.x + ry * e.y;
        }
    const Eigen::Vector3d q = normal.ldlt().solve(right);
    return {q(2), {q(0), q(1)}};
}

Point2 planar_command_for(const PlanarVector& p, Point2 intended_mm, double abbe_height_mm,
                          const SmallRigidMotion& rigid) {
    // The machine lands at c + e(c); the job should land on the intended point moved by the
    // rigid part (turned exactly, so that the job stays a rigid copy of itself), which the work's
    // zero and heading absorb: solve c + e(c) = that, c = that - e(c).
    const double cw = std::cos(rigid.rotation_rad), sw = std::sin(rigid.rotation_rad);
    const Point2 aim{cw * intended_mm.x - sw * intended_mm.y + rigid.offset_mm.x,
                     sw * intended_mm.x + cw * intended_mm.y + rigid.offset_mm.y};
    Point2 command = aim;
    for (int k = 0; k < 8; ++k) {
        const Point2 e = planar_error_mm(p, command, abbe_height_mm);
        const Point2 next{aim.x - e.x, aim.y - e.y};
        const double step = std::hypot(next.x - command.x, next.y - command.y);
        command = next;
        if (step < 1e-9) break;
    }
    return command;
}

Point2 SeedPlanarForm::error_mm(Point2 at, double z) const {
    return {A * at.y * at.y + B * at.y + C * at.x + D * z,
            E * at.x + F * at.y + G * z + H * at.x * at.y + I * at.x * at.x};
}

PlanarVector planar_from_seed_form(const SeedPlanarForm& f, double z) {
    if (z == 0) throw PlanarModelError("the seed form's z (X3) must not be 0");
    PlanarVector p{};
    const auto& names = planar_parameters();
    const auto set = [&](const char* name, double value) {
        for (std::size_t j = 0; j < names.size(); ++j)
            if (std::string(names[j].name) == name) p[j] = value;
    };
    // e_x: A y^2 (the y axis bows), B y (the y axis rolls over the lever z), C x (x scale),
    // D z (the tool leans); e_y: E x (out of square), F y (y scale), G z (the tool leans the
    // other way), H x y (the gantry yaws with y), I x^2 (the x axis bows).
    set("y_straightness", f.A);
    set("y_roll_rate", -f.B / z);
    set("x_scale", f.C);
    set("tool_tilt_about_y", -f.D);
    set("xy_squareness", f.E);
    set("y_scale", f.F);
    set("tool_tilt_about_x", f.G);
    set("gantry_yaw_rate", f.H);
    set("x_straightness", f.I);
    return p;
}

namespace {

// The machine's frame in the camera's, from the rigid `placement`, refined with the parameters
// (the linearised rotation is exact to second order; two refinements leave nothing of it):
// the last solve's parameters and the residual it solved for, `placement` updated.
std::pair<Eigen::VectorXd, Eigen::VectorXd> refine_placement(const Eigen::MatrixXd& a,
                                                             const std::vector<Point2>& commanded,
                                                             const std::vector<Point2>& seen,
                                                             double span,
                                                             geometry::RigidPlacement& placement) {
    Eigen::VectorXd q;
    Eigen::VectorXd r(a.rows());
    for (int iteration = 0; iteration < 4; ++iteration) {
        const double c = std::cos(placement.angle_rad), sn = std::sin(placement.angle_rad);
        for (std::size_t i = 0; i < seen.size(); ++i) {
            // Seen, carried back into the machine's frame, minus commanded.
            const double dx = seen[i].x - placement.translation_mm.x,
                         dy = seen[i].y - placement.translation_mm.y;
            r(2 * static_cast<Eigen::Index>(i)) = c * dx + sn * dy - commanded[i].x;
            r(2 * static_cast<Eigen::Index>(i) + 1) = -sn * dx + c * dy - commanded[i].y;
        }
        q = a.colPivHouseholderQr().solve(r);
        // Fold the fitted small placement (in the machine's frame) into the placement.
        const double w = q(0) / span;  // the rotation's column is in units of the span
        const Point2 t{q(1), q(2)};
        const Point2 t_camera{c * t.x - sn * t.y, sn * t.x + c * t.y};
        placement.translation_mm = {placement.translation_mm.x + t_camera.x,
                                    placement.translation_mm.y + t_camera.y};
        placement.angle_rad += w;
        // The translation is about the machine's origin; a rotation about it moves nothing else.
        if (std::abs(w) < 1e-12 && t.x * t.x + t.y * t.y < 1e-18) break;
    }
    return {q, r};
}

}  // namespace

PlanarFit fit_planar_errors(const std::vector<PlanarObservation>& observations,
                            const PlanarFitSettings& settings) {
    if (observations.size() < 3)
        throw PlanarModelError("fit: " + std::to_string(observations.size()) +
                               " points; the placement alone needs 3");
    std::vector<Point2> commanded, seen;
    for (const auto& o : observations) {
        if (!std::isfinite(o.seen_mm.x) || !std::isfinite(o.seen_mm.y))
            throw PlanarModelError("fit: a measured point is not finite");
        commanded.push_back(o.commanded_mm);
        seen.push_back(o.seen_mm);
    }
    const double span = span_of(commanded);
    if (!(span > 0)) throw PlanarModelError("fit: the points all lie at the origin");
    const double h = settings.abbe_height_mm;
    const Eigen::MatrixXd all = full_design(commanded, h, span);
    const ColumnChoice choice = choose_columns(all, settings.separability);
    const Eigen::Index unknowns = static_cast<Eigen::Index>(choice.kept.size());
    if (all.rows() < 2 * unknowns)
        throw PlanarModelError("fit: " + std::to_string(observations.size()) + " points give " +
                               std::to_string(all.rows()) + " coordinates for " +
                               std::to_string(unknowns) +
                               " unknowns; at least twice as many are needed");
    const Eigen::MatrixXd a = kept_columns(all, choice.kept);
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(a);
    const auto& s = svd.singularValues();
    PlanarFit fit;
    fit.rank = static_cast<int>(choice.kept.size());
    fit.condition = s(0) / s(s.size() - 1);
    fit.held = choice.held;
    if (!(fit.condition < settings.max_condition))
        throw PlanarModelError("fit: the design is too badly conditioned (" +
                               std::to_string(fit.condition) +
                               "): spread the points over the work area");

    auto placement = geometry::best_rigid_placement(commanded, seen);
    const auto [q, r] = refine_placement(a, commanded, seen, span, placement);
    const Eigen::VectorXd residual = r - a * q;
    const double dof = static_cast<double>(a.rows() - unknowns);
    const double variance = residual.squaredNorm() / std::max(1.0, dof);
    fit.residual_rms_mm = std::sqrt(residual.squaredNorm() / static_cast<double>(a.rows()));
    double prior = 0;
    for (const auto& o : observations) prior += o.sigma_mm * o.sigma_mm;
    prior /= static_cast<double>(observations.size());
    if (prior > 0) fit.unit_variance_ratio = std::sqrt(variance / prior);
    const Eigen::MatrixXd covariance = variance * (a.transpose() * a).inverse();
    fit.rotation_rad = placement.angle_rad;
    fit.translation_mm = placement.translation_mm;
    for (Eigen::Index k = kPlacementColumns; k < unknowns; ++k) {
        const int column = choice.kept[static_cast<std::size_t>(k)];
        const auto j = static_cast<std::size_t>(column - kPlacementColumns);
        const double unit = std::pow(span, column_degree(column));
        fit.parameters[j] = q(k) / unit;
        fit.uncertainty[j] = std::sqrt(covariance(k, k)) / unit;
        fit.fitted[j] = true;
    }
    // The residual of the last refinement's solve equals the final one's to first order in q;
    // the final parameters' field against what was seen, exactly:
    for (std::size_t i = 0; i < observations.size(); ++i)
        fit.residuals_mm.push_back({residual(2 * static_cast<Eigen::Index>(i)),
                                    residual(2 * static_cast<Eigen::Index>(i) + 1)});
    return fit;
}

namespace {

// The design matrix's rows per candidate over the columns the candidates separate.
std::vector<Eigen::Matrix<double, 2, Eigen::Dynamic>> candidate_rows(
    const std::vector<Point2>& candidates, double h, double span) {
    const Eigen::MatrixXd all = full_design(candidates, h, span);
    const Eigen::MatrixXd a = kept_columns(all, choose_columns(all, 1e-6).kept);
    std::vector<Eigen::Matrix<double, 2, Eigen::Dynamic>> rows;
    for (std::size_t i = 0; i < candidates.size(); ++i)
        rows.emplace_back(a.middleRows(2 * static_cast<Eigen::Index>(i), 2));
    return rows;
}

}  // namespace

std::vector<std::size_t> detmax_design(const std::vector<Point2>& candidates, std::size_t k,
                                       double abbe_height_mm, unsigned seed) {
    const auto rows = candidate_rows(candidates, abbe_height_mm, span_of(candidates));
    const Eigen::Index n = rows.front().cols();
    if (k * 2 < static_cast<std::size_t>(n) || k > candidates.size())
        throw PlanarModelError("design: " + std::to_string(k) + " points of " +
                               std::to_string(candidates.size()) + " cannot fix " +
                               std::to_string(n) + " unknowns");
    std::mt19937 random(seed);
    std::vector<std::size_t> order(candidates.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), random);
    const std::size_t start = std::max<std::size_t>(1, k > 3 ? k - 3 : 1);
    std::vector<bool> in(candidates.size(), false);
    std::vector<std::size_t> design(order.begin(), order.begin() + static_cast<long>(start));
    // A small ridge keeps the information matrix invertible while the design is too small to
    // fix every unknown; it does not change which point helps most once it is.
    Eigen::MatrixXd m = 1e-9 * Eigen::MatrixXd::Identity(n, n);
    for (std::size_t i : design) m += rows[i].transpose() * rows[i], in[i] = true;
    const auto gain = [&](std::size_t i, const Eigen::MatrixXd& m_inverse) {
        return (Eigen::Matrix2d::Identity() + rows[i] * m_inverse * rows[i].transpose())
            .determinant();
    };
    const auto best_addition = [&](const Eigen::MatrixXd& m_inverse) {
        std::size_t best = candidates.size();
        double best_gain = 0;
        for (std::size_t i = 0; i < candidates.size(); ++i) {
            if (in[i]) continue;
            const double g = gain(i, m_inverse);
            if (g > best_gain) best_gain = g, best = i;
        }
        return best;
    };
    while (design.size() < k) {
        const std::size_t add = best_addition(m.inverse());
        design.push_back(add);
        in[add] = true;
        m += rows[add].transpose() * rows[add];
    }
    // Exchanges: the best addition, then the removal that costs least, while the determinant
    // grows (each exchange raises it, so this ends).
    for (int exchange = 0; exchange < 1000; ++exchange) {
        const std::size_t add = best_addition(m.inverse());
        if (add == candidates.size()) break;
        Eigen::MatrixXd grown = m + rows[add].transpose() * rows[add];
        const Eigen::MatrixXd grown_inverse = grown.inverse();
        std::size_t drop_at = 0;
        double least_loss = 0;
        for (std::size_t d = 0; d < design.size(); ++d) {
            const auto& u = rows[design[d]];
            const double keep =
                (Eigen::Matrix2d::Identity() - u * grown_inverse * u.transpose()).determinant();
            if (keep > least_loss) least_loss = keep, drop_at = d;
        }
        // det(new) / det(old) = gain(add) * keep(drop).
        const double ratio = gain(add, m.inverse()) * least_loss;
        if (!(ratio > 1 + 1e-9)) break;
        const std::size_t dropped = design[drop_at];
        grown -= rows[dropped].transpose() * rows[dropped];
        in[dropped] = false;
        in[add] = true;
        design[drop_at] = add;
        m = grown;
    }
    std::sort(design.begin(), design.end());
    return design;
}

double design_log_determinant(const std::vector<Point2>& points,
                              const std::vector<Point2>& candidates, double abbe_height_mm) {
    const double span = span_of(candidates);
    const auto rows = candidate_rows(candidates, abbe_height_mm, span);
    const Eigen::MatrixXd all = full_design(points, abbe_height_mm, span);
    // The same columns as the candidates separate: chosen on the candidates, applied here.
    const Eigen::MatrixXd universe = full_design(candidates, abbe_height_mm, span);
    const Eigen::MatrixXd a = kept_columns(all, choose_columns(universe, 1e-6).kept);
    const Eigen::MatrixXd m = a.transpose() * a;
    Eigen::LDLT<Eigen::MatrixXd> ldlt(m);
    double log_det = 0;
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
        const double d = ldlt.vectorD()(i);
        if (!(d > 0)) return -std::numeric_limits<double>::infinity();
        log_det += std::log(d);
    }
    return log_det;
}

NormStatistics norm_statistics(const std::vector<Point2>& errors_mm) {
    NormStatistics s;
    s.points = errors_mm.size();
    if (errors_mm.empty()) return s;
    std::vector<double> norms;
    norms.reserve(errors_mm.size());
    for (const auto& e : errors_mm) norms.push_back(std::hypot(e.x, e.y));
    std::sort(norms.begin(), norms.end());
    // Quartiles by linear interpolation between order statistics (the spreadsheet's method).
    const auto quantile = [&](double f) {
        const double at = f * static_cast<double>(norms.size() - 1);
        const auto lo = static_cast<std::size_t>(std::floor(at));
        const std::size_t hi = std::min(lo + 1, norms.size() - 1);
        return norms[lo] + (at - static_cast<double>(lo)) * (norms[hi] - norms[lo]);
    };
    s.min_mm = norms.front();
    s.max_mm = norms.back();
    s.q1_mm = quantile(0.25);
    s.median_mm = quantile(0.5);
    s.q3_mm = quantile(0.75);
    double sum = 0;
    for (double v : norms) sum += v;
    s.mean_mm = sum / static_cast<double>(norms.size());
    double ss = 0;
    for (double v : norms) ss += (v - s.mean_mm) * (v - s.mean_mm);
    // The sample standard deviation, as the seed reports it.
    s.std_mm = norms.size() > 1 ? std::sqrt(ss / static_cast<double>(norms.size() - 1)) : 0;
    return s;
}

}  // namespace calbox::models
