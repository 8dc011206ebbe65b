#include "core/solve/view_stitching.hpp"

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>

namespace calbox::solve {

using geometry::Point2;

Point2 ViewStitch::place(std::size_t v, Point2 b) const {
    const double c = std::cos(angle_rad[v]), sn = std::sin(angle_rad[v]);
    return Point2{c * b.x - sn * b.y + shift_mm[v].x, sn * b.x + c * b.y + shift_mm[v].y};
}

namespace {

// Every point where its views place it now, averaged.
void average_places(const std::vector<std::vector<std::optional<Point2>>>& seen,
                    ViewStitch& stitch) {
    const std::size_t n_views = seen.size(), n_points = stitch.position_mm.size();
    for (std::size_t h = 0; h < n_points; ++h) {
        Point2 sum;
        int n = 0;
        for (std::size_t v = 0; v < n_views; ++v)
            if (const auto& b = seen[v][h]) {
                const Point2 p = stitch.place(v, *b);
                sum.x += p.x, sum.y += p.y, ++n;
            }
        if (n > 0) stitch.position_mm[h] = {sum.x / n, sum.y / n};
    }
}

// One Gauss-Newton step over every view's turn and shift (the first view's fixed: it sets the
// frame) and every shared point's place: a point seen in view v at b lies at R(angle_v) b +
// shift_v. Returns the largest change of a shift.
double stitch_step(const std::vector<std::vector<std::optional<Point2>>>& seen,
                   const std::vector<long>& unknown_of_point, Eigen::Index unknowns,
                   ViewStitch& stitch) {
    const std::size_t n_views = seen.size(), n_points = unknown_of_point.size();
    std::vector<Eigen::Triplet<double>> entries;
    std::vector<double> residual;
    for (std::size_t v = 0; v < n_views; ++v)
        for (std::size_t h = 0; h < n_points; ++h) {
            if (!seen[v][h] || unknown_of_point[h] < 0) continue;
            const Point2 p = stitch.place(v, *seen[v][h]);
            const auto row = static_cast<Eigen::Index>(residual.size());
            residual.push_back(stitch.position_mm[h].x - p.x);
            residual.push_back(stitch.position_mm[h].y - p.y);
            if (v > 0) {
                const auto k = 3 * static_cast<Eigen::Index>(v - 1);
                // d(place)/d(angle) = (-(p.y - shift.y), p.x - shift.x).
                entries.emplace_back(row, k, -(p.y - stitch.shift_mm[v].y));
                entries.emplace_back(row + 1, k, p.x - stitch.shift_mm[v].x);
                entries.emplace_back(row, k + 1, 1.0);
                entries.emplace_back(row + 1, k + 2, 1.0);
            }
            entries.emplace_back(row, unknown_of_point[h], -1.0);
            entries.emplace_back(row + 1, unknown_of_point[h] + 1, -1.0);
        }
    if (residual.empty()) throw StitchError("the views share no point");
    Eigen::SparseMatrix<double> jacobian(static_cast<Eigen::Index>(residual.size()), unknowns);
    jacobian.setFromTriplets(entries.begin(), entries.end());
    const Eigen::Map<const Eigen::VectorXd> r(residual.data(),
                                              static_cast<Eigen::Index>(residual.size()));
    const Eigen::SparseMatrix<double> normal = jacobian.transpose() * jacobian;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
    const Eigen::VectorXd step = solver.solve(jacobian.transpose() * r);
    if (solver.info() != Eigen::Success)
        throw StitchError("the views' shared points do not fix how they lie");
    double largest = 0;
    for (std::size_t v = 1; v < n_views; ++v) {
        const auto k = 3 * static_cast<Eigen::Index>(v - 1);
        stitch.angle_rad[v] += step(k);
        stitch.shift_mm[v].x += step(k + 1);
        stitch.shift_mm[v].y += step(k + 2);
        largest = std::max({largest, std::abs(step(k + 1)), std::abs(step(k + 2))});
    }
    for (std::size_t h = 0; h < n_points; ++h)
        if (unknown_of_point[h] >= 0) {
            stitch.position_mm[h].x += step(unknown_of_point[h]);
            stitch.position_mm[h].y += step(unknown_of_point[h] + 1);
        }
    return largest;
}

}  // namespace

ViewStitch stitch_views(const std::vector<std::vector<std::optional<Point2>>>& seen,
                        std::vector<Point2> start_shift_mm) {
    const std::size_t n_views = seen.size();
    const std::size_t n_points = n_views == 0 ? 0 : seen[0].size();
    ViewStitch stitch;
    stitch.angle_rad.assign(n_views, 0);
    stitch.shift_mm = std::move(start_shift_mm);
    stitch.position_mm.assign(n_points, Point2{});
    average_places(seen, stitch);
    if (n_views < 2) return stitch;
    std::vector<long> unknown_of_point(n_points, -1);
    auto unknowns = 3 * static_cast<Eigen::Index>(n_views - 1);
    for (std::size_t h = 0; h < n_points; ++h) {
        int views = 0;
        for (std::size_t v = 0; v < n_views; ++v) views += seen[v][h] ? 1 : 0;
        if (views > 1) unknown_of_point[h] = unknowns, unknowns += 2;
    }
    for (int iteration = 0; iteration < 6; ++iteration)
        if (stitch_step(seen, unknown_of_point, unknowns, stitch) < 1e-9) break;
    average_places(seen, stitch);
    return stitch;
}

}  // namespace calbox::solve
