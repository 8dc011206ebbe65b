#include "core/targets/galvo_target.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>

#include "core/number_text.hpp"

namespace calbox::targets {
using drawings::Contour;
using drawings::FillRule;
using jobs::FillSettings;
using jobs::JobError;
using jobs::Move;
using jobs::MoveKind;
using jobs::PlacedJob;
using jobs::plan_fill;
using jobs::Toolpath;
namespace {

using geometry::Point2;

// The large circles, as offsets in columns and rows from the grid's middle node: an L of four
// round the middle (its arms of unequal length, so that no quarter turn or mirror image maps it
// onto itself) and four more spread over the field, chosen by search so that every rotation and
// mirror image moves at least five of the eight onto small marks: a few missing or damaged marks
// cannot make a wrong reading look right.
constexpr std::array<std::array<int, 2>, 8> kLargeOffsets{
    {{0, 0}, {1, 0}, {2, 0}, {0, 1}, {-9, 10}, {1, -9}, {-12, -4}, {5, 6}}};

// The circles' radii, in pitches.
constexpr double kSmallRadiusPitches = 0.2, kLargeRadiusPitches = 0.4;

Contour circle(Point2 centre, double radius_mm) {
    // Enough sides that the polygon lies within a micrometre of the circle.
    const int sides = std::max(
        24, static_cast<int>(std::ceil(3.14159265358979 / std::acos(1 - 0.001 / radius_mm))));
    Contour c;
    c.closed = true;
    for (int k = 0; k < sides; ++k) {
        const double a = 2 * 3.14159265358979323846 * k / sides;
        c.points.push_back(
            {centre.x + radius_mm * std::cos(a), centre.y + radius_mm * std::sin(a)});
    }
    return c;
}

// The k-th circle burned on a row: row by row, alternate rows backwards, so that the beam never
// jumps across the field.
int burned_column(int row, int k, int grid_count) {
    return row % 2 == 0 ? k : grid_count - 1 - k;
}

}  // namespace

bool is_large_mark(GridIndex index, int grid_count) {
    const int middle = grid_count / 2;
    // Far-out offsets scale with the grid so that smaller grids keep the same layout.
    const double reach = (grid_count - 1) / 30.0;
    for (const auto& o : kLargeOffsets) {
        const bool near = std::abs(o[0]) <= 2 && std::abs(o[1]) <= 2;
        const int c = middle + (near ? o[0] : static_cast<int>(std::lround(o[0] * reach)));
        const int r = middle + (near ? o[1] : static_cast<int>(std::lround(o[1] * reach)));
        if (index.column == c && index.row == r) return true;
    }
    return false;
}

GridIndex apply_symmetry(int symmetry, GridIndex i, int grid_count) {
    const int n = grid_count - 1;
    GridIndex q = i;
    if (symmetry >= 4) q = {n - q.column, q.row};  // mirror across the middle column first
    for (int k = 0; k < symmetry % 4; ++k) q = {n - q.row, q.column};  // a quarter turn
    return q;
}

GalvoTarget galvo_grid(const models::MachineFile& machine, const GalvoTargetOptions& options) {
    if (!machine.is_galvo() || !machine.galvo)
        throw JobError("the galvo target is for a galvo machine (kind = \"galvo\"), not a " +
                       machine.kind);
    if (options.grid_count < 7 || options.grid_count > 101)
        throw JobError("the grid must have 7 to 101 circles a side, not " +
                       std::to_string(options.grid_count));
    GalvoTarget target;
    target.grid_count = options.grid_count;
    // The outer large circles' edges stay inside the field.
    target.pitch_mm = machine.galvo->field_size_mm / options.grid_count;
    const double small_radius = kSmallRadiusPitches * target.pitch_mm;
    if (machine.tool_width_mm > small_radius)
        throw JobError("the spot (tool_width_mm " + number_text("%g", machine.tool_width_mm) +
                       " mm) is too large for circles of " + number_text("%.3f", small_radius) +
                       " mm radius: use a smaller grid count");
    const double middle = (options.grid_count - 1) / 2.0;
    std::string canonical =
        models::fingerprint(machine) + "|galvo-grid|" + std::to_string(options.grid_count);
    for (int row = 0; row < options.grid_count; ++row) {
        for (int column = 0; column < options.grid_count; ++column) {
            GalvoMark mark;
            mark.index = {column, row};
            mark.centre_mm = {(column - middle) * target.pitch_mm,
                              (row - middle) * target.pitch_mm};
            mark.large = is_large_mark(mark.index, options.grid_count);
            target.marks.push_back(mark);
        }
    }
    // The large marks in the order the job burns them (below), as fingerprints have always
    // listed them.
    for (int row = 0; row < options.grid_count; ++row)
        for (int k = 0; k < options.grid_count; ++k) {
            const int column = burned_column(row, k, options.grid_count);
            if (target.at({column, row}).large)
                canonical += "|L" + std::to_string(column) + "," + std::to_string(row);
        }
    target.fingerprint = models::digest(canonical + "|" + number_text("%.6f", target.pitch_mm));
    return target;
}

GalvoTarget make_galvo_target(const models::MachineFile& machine,
                              const GalvoTargetOptions& options) {
    GalvoTarget target = galvo_grid(machine, options);
    const double small_radius = kSmallRadiusPitches * target.pitch_mm,
                 large_radius = kLargeRadiusPitches * target.pitch_mm;
    FillSettings fill;
    fill.line_width_mm = machine.tool_width_mm;
    fill.spacing_mm = machine.tool_width_mm;
    fill.angle_deg = 0;
    Point2 pen{0, 0};
    PlacedJob& job = target.job;
    job.line_width_mm = machine.tool_width_mm;
    job.spacing_mm = machine.tool_width_mm;
    job.feed_mm_s = machine.feed_mm_s;
    // Every circle of a size is filled alike: the fill is planned once about the origin for each
    // size and each place the beam comes from (a few in all: the serpentine repeats), and moved
    // to each circle's centre. The scanlines were centred on each circle already: the same
    // moves as filling each in place, to Clipper's integer grid, for a few fills rather than 961
    // (Clipper's work was most of the target's time).
    struct Fill {
        Toolpath about_origin;
        Point2 pen_after;  // where the beam ends, from the centre
    };
    std::map<std::tuple<bool, long long, long long>, Fill> fills;
    const auto nanometres = [](double mm) { return std::llround(mm * 1e6); };
    for (int row = 0; row < options.grid_count; ++row)
        for (int k = 0; k < options.grid_count; ++k) {
            const GalvoMark& mark = target.at({burned_column(row, k, options.grid_count), row});
            const Point2 c = mark.centre_mm;
            const Point2 from{pen.x - c.x, pen.y - c.y};
            auto [at, fresh] =
                fills.try_emplace({mark.large, nanometres(from.x), nanometres(from.y)});
            Fill& f = at->second;
            if (fresh) {
                f.pen_after = from;
                f.about_origin =
                    plan_fill({circle({0, 0}, mark.large ? large_radius : small_radius)},
                              FillRule::nonzero, fill, f.pen_after);
            }
            for (const Move& m : f.about_origin.moves)
                job.toolpath.moves.push_back(
                    {{m.from.x + c.x, m.from.y + c.y}, {m.to.x + c.x, m.to.y + c.y}, m.kind});
            // The first move starts where the beam stood (the key rounds it to a nanometre).
            if (!f.about_origin.moves.empty())
                job.toolpath.moves[job.toolpath.moves.size() - f.about_origin.moves.size()].from =
                    pen;
            pen = {f.pen_after.x + c.x, f.pen_after.y + c.y};
        }
    const double half = machine.galvo->field_size_mm / 2;
    job.min_x = job.min_y = -half;
    job.max_x = job.max_y = half;
    return target;
}

std::string write_scanner_job_csv(const PlacedJob& job, const models::MachineFile& machine) {
    std::string out = "x_mm,y_mm,power\n";
    char line[96];
    Point2 at{1e300, 1e300};
    for (const auto& move : job.toolpath.moves) {
        const bool marking = move.kind != MoveKind::travel;
        if (marking && (move.from.x != at.x || move.from.y != at.y)) {
            std::snprintf(line, sizeof line, "%.4f,%.4f,0\n", move.from.x, move.from.y);
            out += line;
        }
        std::snprintf(line, sizeof line, "%.4f,%.4f,%.3f\n", move.to.x, move.to.y,
                      marking ? machine.laser_power : 0.0);
        out += line;
        at = move.to;
    }
    return out;
}

}  // namespace calbox::targets
