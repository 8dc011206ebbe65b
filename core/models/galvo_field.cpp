#include "core/models/galvo_field.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/geometry/placement.hpp"
#include "core/number_text.hpp"

namespace calbox::models {
namespace {

using geometry::Point2;

Point2 operator+(Point2 a, Point2 b) {
    return {a.x + b.x, a.y + b.y};
}
Point2 operator-(Point2 a, Point2 b) {
    return {a.x - b.x, a.y - b.y};
}
Point2 operator*(double s, Point2 a) {
    return {s * a.x, s * a.y};
}

// Catmull-Rom weights for the four nodes around a point at fraction t of its interval.
std::array<double, 4> catmull_rom(double t) {
    const double t2 = t * t, t3 = t2 * t;
    return {0.5 * (-t3 + 2 * t2 - t), 0.5 * (3 * t3 - 5 * t2 + 2), 0.5 * (-3 * t3 + 4 * t2 + t),
            0.5 * (t3 - t2)};
}

// The fourth difference along a row or a column of five measured nodes cancels any field up to a
// cubic along it (a scanner's distortion is smooth over five pitches), leaving the nodes' own
// scatter: each such difference of independent errors of variance s^2 per axis has variance
// 70 s^2 per axis. Its squared length then follows 70 s^2 times a chi-square of two degrees of
// freedom, whose median is 2 ln 2: the median keeps a spattered or chipped mark from swaying it.
// The fourth difference of the landing errors over five nodes from (c, r) along a row (or down
// column r from row c); nothing where one of them was not measured.
std::optional<Point2> fourth_difference(int n, const std::vector<std::optional<Point2>>& measured,
                                        const std::vector<Point2>& landed_mm,
                                        const SquareGrid& grid, bool along_rows, int r, int c) {
    constexpr std::array<double, 5> kFourthDifference{1, -4, 6, -4, 1};
    Point2 d;
    for (int k = 0; k < 5; ++k) {
        const int column = along_rows ? c + k : r, row = along_rows ? r : c + k;
        const std::size_t i = geometry::grid_offset(column, row, n);
        if (!measured[i]) return std::nullopt;
        d = d + kFourthDifference[static_cast<std::size_t>(k)] *
                    (landed_mm[i] - grid.node_mm(column, row));
    }
    return d;
}

double node_scatter(int n, const std::vector<std::optional<Point2>>& measured,
                    const std::vector<Point2>& landed_mm, const SquareGrid& grid) {
    std::vector<double> squared;
    for (const bool along_rows : {true, false})
        for (int r = 0; r < n; ++r)
            for (int c = 0; c + 4 < n; ++c)
                if (const auto d =
                        fourth_difference(n, measured, landed_mm, grid, along_rows, r, c))
                    squared.push_back(d->x * d->x + d->y * d->y);
    if (squared.size() < 20) return 0;
    const auto middle = squared.begin() + static_cast<std::ptrdiff_t>(squared.size() / 2);
    std::nth_element(squared.begin(), middle, squared.end());
    const double per_axis_variance = *middle / (70 * 2 * std::log(2.0));
    return std::sqrt(2 * per_axis_variance);
}
}  // namespace

Point2 SquareGrid::node_mm(int column, int row) const {
    const double middle = 0.5 * (count - 1);
    return {(column - middle) * pitch_mm, (row - middle) * pitch_mm};
}

GridMap::GridMap(SquareGrid grid, std::vector<Point2> values)
    : grid_(grid), values_(std::move(values)) {
    if (grid_.count < 2 || values_.size() != geometry::grid_nodes(grid_.count))
        throw FieldError("a grid map needs a value at every node of a grid of at least 2 x 2");
}

Point2 GridMap::node(int column, int row) const {
    // One node beyond an edge continues the edge's last interval linearly.
    const int n = grid_.count;
    if (column < 0) return 2.0 * node(0, row) - node(1, row);
    if (column >= n) return 2.0 * node(n - 1, row) - node(n - 2, row);
    if (row < 0) return 2.0 * node(column, 0) - node(column, 1);
    if (row >= n) return 2.0 * node(column, n - 1) - node(column, n - 2);
    return values_[geometry::grid_offset(column, row, n)];
}

Point2 GridMap::operator()(Point2 at) const {
    const double gx = at.x / grid_.pitch_mm + 0.5 * (grid_.count - 1);
    const double gy = at.y / grid_.pitch_mm + 0.5 * (grid_.count - 1);
    const int i = std::clamp(static_cast<int>(std::floor(gx)), 0, grid_.count - 2);
    const int k = std::clamp(static_cast<int>(std::floor(gy)), 0, grid_.count - 2);
    const auto wx = catmull_rom(gx - i), wy = catmull_rom(gy - k);
    Point2 out;
    for (int b = 0; b < 4; ++b) {
        Point2 row;
        for (int a = 0; a < 4; ++a)
            row = row + wx[static_cast<std::size_t>(a)] * node(i - 1 + a, k - 1 + b);
        out = out + wy[static_cast<std::size_t>(b)] * row;
    }
    return out;
}

Point2 CorrectionTable::node_mm(int column, int row) const {
    return {min_x_mm + (max_x_mm - min_x_mm) * column / (nodes - 1),
            min_y_mm + (max_y_mm - min_y_mm) * row / (nodes - 1)};
}

bool CorrectionTable::covers(Point2 q) const {
    const double slack = 1e-9;
    return q.x >= min_x_mm - slack && q.x <= max_x_mm + slack && q.y >= min_y_mm - slack &&
           q.y <= max_y_mm + slack;
}

Point2 CorrectionTable::command_for(Point2 q) const {
    const double gx = std::clamp((q.x - min_x_mm) / (max_x_mm - min_x_mm), 0.0, 1.0) * (nodes - 1);
    const double gy = std::clamp((q.y - min_y_mm) / (max_y_mm - min_y_mm), 0.0, 1.0) * (nodes - 1);
    const int i = std::min(static_cast<int>(gx), nodes - 2);
    const int k = std::min(static_cast<int>(gy), nodes - 2);
    const double tx = gx - i, ty = gy - k;
    const auto correction = [&](int c, int r) {
        return command_mm[geometry::grid_offset(c, r, nodes)] - node_mm(c, r);
    };
    const Point2 low = (1 - tx) * correction(i, k) + tx * correction(i + 1, k);
    const Point2 high = (1 - tx) * correction(i, k + 1) + tx * correction(i + 1, k + 1);
    return q + ((1 - ty) * low + ty * high);
}

CorrectionTable identity_table(double half_span_mm, int nodes) {
    CorrectionTable t;
    t.nodes = nodes;
    t.min_x_mm = t.min_y_mm = -half_span_mm;
    t.max_x_mm = t.max_y_mm = half_span_mm;
    for (int r = 0; r < nodes; ++r)
        for (int c = 0; c < nodes; ++c) t.command_mm.push_back(t.node_mm(c, r));
    return t;
}

ErrorStatistics error_statistics(const std::vector<Point2>& errors) {
    ErrorStatistics s;
    s.points = errors.size();
    if (errors.empty()) return s;
    double sum = 0, sum2 = 0;
    for (const auto& e : errors) {
        const double norm = std::hypot(e.x, e.y);
        sum += norm;
        sum2 += norm * norm;
        s.max_mm = std::max(s.max_mm, norm);
    }
    s.mean_mm = sum / static_cast<double>(errors.size());
    s.rms_mm = std::sqrt(sum2 / static_cast<double>(errors.size()));
    return s;
}

namespace {

// A node without a mark: a quadratic in the grid indices fitted to the displacement of the
// measured nodes around it (5 x 5, wider if that holds too few).
// The landing error at node (c, r) from a quadratic fitted to the marked nodes within `reach`
// of it; nothing with fewer than 12 of them.
std::optional<Point2> local_quadratic_error(const SquareGrid& grid,
                                            const std::vector<std::optional<Point2>>& landed,
                                            const std::vector<Point2>& landed_mm, int c, int r,
                                            int reach) {
    const int n = grid.count;
    const auto index = [n](int col, int row) { return geometry::grid_offset(col, row, n); };
    std::vector<std::array<double, 6>> rows;
    std::vector<Point2> values;
    for (int rr = std::max(0, r - reach); rr <= std::min(n - 1, r + reach); ++rr)
        for (int cc = std::max(0, c - reach); cc <= std::min(n - 1, c + reach); ++cc) {
            if (!landed[index(cc, rr)]) continue;
            const double u = cc - c, v = rr - r;
            rows.push_back({1, u, v, u * u, u * v, v * v});
            values.push_back(landed_mm[index(cc, rr)] - grid.node_mm(cc, rr));
        }
    if (rows.size() < 12) return std::nullopt;
    Eigen::MatrixXd a(static_cast<long>(rows.size()), 6);
    Eigen::MatrixXd b(static_cast<long>(rows.size()), 2);
    for (std::size_t i = 0; i < rows.size(); ++i) {
        for (int j = 0; j < 6; ++j)
            a(static_cast<long>(i), j) = rows[i][static_cast<std::size_t>(j)];
        b(static_cast<long>(i), 0) = values[i].x;
        b(static_cast<long>(i), 1) = values[i].y;
    }
    const Eigen::MatrixXd coefficients = a.colPivHouseholderQr().solve(b);
    return Point2{coefficients(0, 0), coefficients(0, 1)};
}

void fill_unmarked_nodes(const SquareGrid& grid, const std::vector<std::optional<Point2>>& landed,
                         FieldFit& fit) {
    const int n = grid.count;
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) {
            const std::size_t at = geometry::grid_offset(c, r, n);
            if (landed[at]) continue;
            for (int reach = 2; reach <= n; ++reach)
                if (const auto error =
                        local_quadratic_error(grid, landed, fit.landed_mm, c, r, reach)) {
                    fit.landed_mm[at] = grid.node_mm(c, r) + *error;
                    fit.filled[at] = true;
                    break;
                }
        }
}

// The table over the largest rectangle inside the measured field (from its border columns and
// rows), each node's command the one that lands on it through what was burned, and how far the
// table's interpolation is from that between its nodes.
void correction_table(const SquareGrid& grid, const GridMap& lands,
                      const CorrectionTable& burned_through, int table_nodes, FieldFit& fit) {
    const int n = grid.count;
    const auto index = [n](int c, int r) { return geometry::grid_offset(c, r, n); };
    CorrectionTable& t = fit.table;
    t.nodes = table_nodes;
    t.min_x_mm = t.min_y_mm = -1e300;
    t.max_x_mm = t.max_y_mm = 1e300;
    for (int j = 0; j < n; ++j) {
        t.min_x_mm = std::max(t.min_x_mm, fit.landed_mm[index(0, j)].x);
        t.max_x_mm = std::min(t.max_x_mm, fit.landed_mm[index(n - 1, j)].x);
        t.min_y_mm = std::max(t.min_y_mm, fit.landed_mm[index(j, 0)].y);
        t.max_y_mm = std::min(t.max_y_mm, fit.landed_mm[index(j, n - 1)].y);
    }
    if (!(t.max_x_mm - t.min_x_mm > grid.pitch_mm && t.max_y_mm - t.min_y_mm > grid.pitch_mm))
        throw FieldError(
            "the measured field encloses no rectangle: the grid is folded or mirrored");
    // Where to aim (in the grid's intended space) to land on q: u = q - (lands(u) - u), a
    // contraction while the field's distortion changes by well under 100 % per millimetre.
    const auto aim_for = [&](Point2 q) {
        Point2 u = q;
        for (int iteration = 0; iteration < 100; ++iteration) {
            const Point2 miss = lands(u) - q;
            u = u - miss;
            if (std::hypot(miss.x, miss.y) < 1e-10) return u;
        }
        throw FieldError("the field map cannot be inverted near X" + number_text("%.2f", q.x) +
                         " Y" + number_text("%.2f", q.y) + ": the measured grid folds there");
    };
    t.command_mm.clear();
    for (int r = 0; r < t.nodes; ++r)
        for (int c = 0; c < t.nodes; ++c)
            t.command_mm.push_back(burned_through.command_for(aim_for(t.node_mm(c, r))));
    double sum2 = 0;
    int count = 0;
    for (int r = 0; r + 1 < t.nodes; ++r)
        for (int c = 0; c + 1 < t.nodes; ++c) {
            const Point2 a = t.node_mm(c, r), b = t.node_mm(c + 1, r + 1);
            const Point2 middle = 0.5 * (a + b);
            const Point2 d = t.command_for(middle) - burned_through.command_for(aim_for(middle));
            const double e = std::hypot(d.x, d.y);
            sum2 += e * e, ++count;
            fit.table_interpolation_max_mm = std::max(fit.table_interpolation_max_mm, e);
        }
    fit.table_interpolation_rms_mm = std::sqrt(sum2 / std::max(1, count));
}

}  // namespace

FieldFit fit_galvo_field(const SquareGrid& grid, const std::vector<std::optional<Point2>>& landed,
                         const CorrectionTable& burned_through, int table_nodes) {
    const int n = grid.count;
    if (n < 4 || landed.size() != geometry::grid_nodes(n))
        throw FieldError("the field map needs a grid of at least 4 x 4 and one entry per node");
    if (table_nodes < 2 || table_nodes > 1025)
        throw FieldError("a table has 2 to 1025 nodes a side");
    const auto index = [n](int c, int r) { return geometry::grid_offset(c, r, n); };
    std::vector<Point2> from, to;
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c)
            if (landed[index(c, r)])
                from.push_back(*landed[index(c, r)]), to.push_back(grid.node_mm(c, r));
    if (from.size() * 4 < landed.size() * 3)
        throw FieldError("only " + std::to_string(from.size()) + " of " +
                         std::to_string(landed.size()) +
                         " grid marks were measured (three quarters needed)");
    bool column0 = false, column_n = false, row0 = false, row_n = false;
    for (int j = 0; j < n; ++j) {
        column0 = column0 || landed[index(0, j)], column_n = column_n || landed[index(n - 1, j)];
        row0 = row0 || landed[index(j, 0)], row_n = row_n || landed[index(j, n - 1)];
    }
    if (!(column0 && column_n && row0 && row_n))
        throw FieldError(
            "a whole border row or column of the grid is missing: the field's edge is unknown");
    const auto onto_grid = geometry::best_rigid_placement(from, to);

    FieldFit fit;
    fit.landed_mm.assign(landed.size(), {});
    fit.filled.assign(landed.size(), false);
    std::vector<Point2> errors;
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c)
            if (landed[index(c, r)]) {
                fit.landed_mm[index(c, r)] = onto_grid.apply(*landed[index(c, r)]);
                errors.push_back(fit.landed_mm[index(c, r)] - grid.node_mm(c, r));
            }
    fit.before = error_statistics(errors);
    fit.node_scatter_mm = node_scatter(n, landed, fit.landed_mm, grid);
    fill_unmarked_nodes(grid, landed, fit);
    correction_table(grid, GridMap(grid, fit.landed_mm), burned_through, table_nodes, fit);
    return fit;
}

std::string table_to_csv(const CorrectionTable& t) {
    std::ostringstream out;
    char line[200];
    std::snprintf(
        line, sizeof line,
        "# calbox galvo correction table: %d x %d nodes over X %.6f..%.6f Y %.6f..%.6f mm\n",
        t.nodes, t.nodes, t.min_x_mm, t.max_x_mm, t.min_y_mm, t.max_y_mm);
    out << line << "column,row,x_mm,y_mm,command_x_mm,command_y_mm\n";
    for (int r = 0; r < t.nodes; ++r)
        for (int c = 0; c < t.nodes; ++c) {
            const Point2 q = t.node_mm(c, r),
                         s = t.command_mm[geometry::grid_offset(c, r, t.nodes)];
            std::snprintf(line, sizeof line, "%d,%d,%.6f,%.6f,%.6f,%.6f\n", c, r, q.x, q.y, s.x,
                          s.y);
            out << line;
        }
    return out.str();
}

CorrectionTable table_from_csv(const std::string& text, const std::string& source) {
    std::istringstream in(text);
    std::string line;
    int number = 0;
    struct Row {
        int column, row;
        double x, y, cx, cy;
    };
    std::vector<Row> rows;
    while (std::getline(in, line)) {
        ++number;
        if (line.empty() || line[0] == '#' || line.rfind("column", 0) == 0) continue;
        Row r{};
        char tail = 0;
        if (std::sscanf(line.c_str(), "%d,%d,%lf,%lf,%lf,%lf%c", &r.column, &r.row, &r.x, &r.y,
                        &r.cx, &r.cy, &tail) != 6 ||
            !std::isfinite(r.x) || !std::isfinite(r.y) || !std::isfinite(r.cx) ||
            !std::isfinite(r.cy))
            throw FieldError(source + ":" + std::to_string(number) +
                             ": expected column,row,x_mm,y_mm,command_x_mm,command_y_mm");
        rows.push_back(r);
    }
    const int nodes = static_cast<int>(std::lround(std::sqrt(static_cast<double>(rows.size()))));
    if (nodes < 2 || geometry::grid_nodes(nodes) != rows.size())
        throw FieldError(source + ": " + std::to_string(rows.size()) +
                         " nodes is not a square table");
    CorrectionTable t;
    t.nodes = nodes;
    t.min_x_mm = rows.front().x, t.min_y_mm = rows.front().y;
    t.max_x_mm = rows.back().x, t.max_y_mm = rows.back().y;
    if (!(t.max_x_mm > t.min_x_mm && t.max_y_mm > t.min_y_mm))
        throw FieldError(source + ": the table's nodes do not span a rectangle");
    t.command_mm.resize(rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const Row& r = rows[i];
        const Point2 expected = t.node_mm(r.column, r.row);
        if (r.column != static_cast<int>(i) % nodes || r.row != static_cast<int>(i) / nodes ||
            std::abs(expected.x - r.x) > 1e-5 || std::abs(expected.y - r.y) > 1e-5)
            throw FieldError(
                source + ": node " + std::to_string(i) +
                " is out of order or off the regular grid (row by row from the lowest x and y)");
        t.command_mm[i] = {r.cx, r.cy};
    }
    return t;
}

}  // namespace calbox::models
