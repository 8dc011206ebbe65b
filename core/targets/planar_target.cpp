#include "core/targets/planar_target.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include "core/number_text.hpp"

namespace calbox::targets {
using drawings::Contour;
using drawings::FillRule;
using jobs::append;
using jobs::FillSettings;
using jobs::JobError;
using jobs::PlacedJob;
using jobs::plan_fill;
using jobs::write_gcode;
namespace {

using geometry::Point2;

// Every hole is approached from -x and -y, from this far: whatever slack the drives have is
// taken up the same way at every hole, so backlash moves them all alike (a translation the fit
// takes out) instead of scattering them.
constexpr double kApproachMm = 1.0;

// A circle's points, enough that the polygon stays within a micrometre of it.
std::vector<Point2> circle_points(Point2 centre, double radius_mm) {
    const int sides = std::max(
        24, static_cast<int>(std::ceil(std::numbers::pi / std::acos(1 - 0.001 / radius_mm))));
    std::vector<Point2> points;
    for (int k = 0; k <= sides; ++k) {
        const double a = 2 * std::numbers::pi * k / sides;
        points.push_back({centre.x + radius_mm * std::cos(a), centre.y + radius_mm * std::sin(a)});
    }
    return points;
}

// Appended piece by piece: GCC 12 at -O3 misreports "X" + std::string (-Wrestrict, PR105329).
std::string xy(Point2 p) {
    std::string out = "X";
    out += number_text("%.4f", p.x);
    out += " Y";
    out += number_text("%.4f", p.y);
    return out;
}

}  // namespace

std::string write_drilling_job(const models::MachineFile& m, const std::vector<PlanarHole>& holes,
                               double hole_diameter_mm, double large_diameter_mm,
                               const std::string& title) {
    if (!m.planar) throw JobError("a drilling job is for a router, not a " + m.kind);
    const auto& planar = *m.planar;
    const bool marlin = m.firmware == "marlin";
    const auto dwell = [&](double seconds) {
        return marlin ? "G4 P" + number_text("%.0f", seconds * 1000)
                      : "G4 P" + number_text("%.2f", seconds);
    };
    const std::string travel = " F" + number_text("%.0f", m.travel_feed_mm_s * 60),
                      plunge = " F" + number_text("%.0f", planar.plunge_feed_mm_s * 60),
                      feed = " F" + number_text("%.0f", m.feed_mm_s * 60);
    std::string out;
    const auto line = [&](const std::string& text) { out += text + "\n"; };
    line("; " + title);
    line("; Z0 is the sheet's top; every hole is approached from -X -Y");
    line("G21");
    line("G90");
    if (!marlin) line("G17");
    line("G0 Z" + number_text("%.3f", m.safe_height_mm) + travel);
    line("M3 S" + number_text("%.0f", m.spindle_rpm));
    line(dwell(2.0));  // the spindle comes up to speed
    for (const auto& hole : holes) {
        const Point2 c = hole.centre_mm;
        const double from = hole.approached_backwards ? kApproachMm : -kApproachMm;
        line("G0 " + xy({c.x + from, c.y + from}) + travel);
        line("G0 " + xy(c));
        line("G1 Z" + number_text("%.3f", -m.cut_depth_mm) + plunge);
        if (hole.large) {
            // Widened by one circle of the tool's radius around the plunge: the cut reaches
            // twice the tool's radius from the centre, and nothing is left in the middle.
            const double r = 0.5 * (large_diameter_mm - hole_diameter_mm);
            const auto ring = circle_points(c, r);
            line("G1 " + xy(ring.front()) + feed);
            for (std::size_t k = 1; k < ring.size(); ++k) line("G1 " + xy(ring[k]));
            line("G1 " + xy(c));
        }
        line(dwell(planar.dwell_s));
        line("G0 Z" + number_text("%.3f", m.safe_height_mm) + travel);
    }
    line("M5");
    if (!marlin) line("M2");
    return out;
}

bool is_large_hole(GridIndex i, int /*columns*/, int /*rows*/) {
    // Two side by side near the first corner, off every axis and diagonal of the grid.
    return i.row == 2 && (i.column == 1 || i.column == 2);
}

GridIndex omitted_hole(int columns, int /*rows*/) {
    return {columns - 3, 1};
}

GridIndex apply_grid_symmetry(int symmetry, GridIndex i, int columns, int rows) {
    GridIndex q = i;
    int c = columns, r = rows;
    if (symmetry >= 4) q = {c - 1 - q.column, q.row};  // mirror across the middle column
    for (int k = 0; k < symmetry % 4; ++k) {
        q = {r - 1 - q.row, q.column};  // a quarter turn: the rows become columns
        std::swap(c, r);
    }
    return q;
}

std::pair<int, int> grid_dimensions_after(int symmetry, int columns, int rows) {
    return symmetry % 2 == 0 ? std::pair{columns, rows} : std::pair{rows, columns};
}

namespace {

// The design nodes a target is limited to (calbox target planar --only), each inside the grid.
std::set<std::size_t> design_nodes(const PlanarTargetOptions& options, int columns, int rows) {
    std::set<std::size_t> only;
    if (!options.only_nodes) return only;
    for (std::size_t n : *options.only_nodes) {
        if (n >= static_cast<std::size_t>(columns) * static_cast<std::size_t>(rows))
            throw JobError("design node " + std::to_string(n) + " is outside the " +
                           std::to_string(columns) + " x " + std::to_string(rows) + " grid");
        only.insert(n);
    }
    return only;
}

// Printers and lasers: each dot filled with the machine's line, written as its jobs are.
std::string printed_dots_job(const PlanarTarget& t, const models::MachineFile& machine,
                             double line_mm) {
    FillSettings fill;
    fill.line_width_mm = line_mm;
    fill.spacing_mm = line_mm;
    fill.angle_deg = 0;
    PlacedJob job;
    job.line_width_mm = line_mm;
    job.spacing_mm = job.line_width_mm;
    job.feed_mm_s = machine.feed_mm_s;
    Point2 pen{0, 0};
    for (const auto& hole : t.holes) {
        Contour c;
        c.closed = true;
        c.points = circle_points(hole.centre_mm,
                                 0.5 * (hole.large ? t.large_diameter_mm : t.hole_diameter_mm));
        c.points.pop_back();
        append(job.toolpath, plan_fill({c}, FillRule::nonzero, fill, pen));
    }
    job.min_x = job.min_y = 0;
    job.max_x = machine.bed_size_x_mm;
    job.max_y = machine.bed_size_y_mm;
    return write_gcode(job, machine, "calbox planar target");
}

}  // namespace

PlanarTarget make_planar_target(const models::MachineFile& machine,
                                const PlanarTargetOptions& options) {
    if (!machine.is_planar() || !machine.planar)
        throw JobError("the planar target is for a router, cartesian printer or laser, not a " +
                       machine.kind);
    const auto& planar = *machine.planar;
    PlanarTarget t;
    t.pitch_mm = planar.hole_pitch_mm;
    const auto count = [&](double size) {
        return static_cast<int>(std::floor((size - 2 * planar.margin_mm) / t.pitch_mm + 1e-9)) + 1;
    };
    t.columns = count(machine.bed_size_x_mm);
    t.rows = count(machine.bed_size_y_mm);
    if (t.columns < 7 || t.rows < 7)
        throw JobError("the work area holds a " + std::to_string(std::max(0, t.columns)) + " x " +
                       std::to_string(std::max(0, t.rows)) + " grid at " +
                       number_text("%g", t.pitch_mm) +
                       " mm pitch; at least 7 x 7 are needed (lower [planar] hole_pitch_mm or "
                       "margin_mm)");
    // The grid centred on the work area.
    t.first_mm = {0.5 * (machine.bed_size_x_mm - (t.columns - 1) * t.pitch_mm),
                  0.5 * (machine.bed_size_y_mm - (t.rows - 1) * t.pitch_mm)};
    const bool router = machine.tool() == models::MachineTool::spindle;
    // Routers drill with their tool; printers and lasers fill a dot a quarter pitch across.
    t.hole_diameter_mm = router ? machine.tool_width_mm : 0.24 * t.pitch_mm;
    t.large_diameter_mm = 2 * t.hole_diameter_mm;
    if (t.large_diameter_mm > 0.6 * t.pitch_mm)
        throw JobError("holes of " + number_text("%g", t.hole_diameter_mm) + " mm (large ones " +
                       number_text("%g", t.large_diameter_mm) + " mm) are too large for a " +
                       number_text("%g", t.pitch_mm) +
                       " mm pitch: the large ones must stay under 0.6 pitch");
    const double line_mm = machine.is_printer() ? machine.line_width_mm : machine.tool_width_mm;
    if (!router && line_mm > 0.25 * t.hole_diameter_mm)
        throw JobError("the line (" + number_text("%g", line_mm) +
                       " mm) is too wide to fill dots of " + number_text("%g", t.hole_diameter_mm) +
                       " mm");
    t.omitted = omitted_hole(t.columns, t.rows);
    const std::set<std::size_t> only = design_nodes(options, t.columns, t.rows);
    std::string canonical = models::fingerprint(machine) + "|planar-grid|" +
                            std::to_string(t.columns) + "x" + std::to_string(t.rows) + "|" +
                            number_text("%.6f", t.pitch_mm) + "|" +
                            number_text("%.6f", t.hole_diameter_mm);
    // Row by row, alternate rows backwards, so the tool never crosses the sheet empty.
    for (int row = 0; row < t.rows; ++row)
        for (int k = 0; k < t.columns; ++k) {
            const GridIndex i{row % 2 == 0 ? k : t.columns - 1 - k, row};
            if (i == t.omitted) continue;
            const bool large = is_large_hole(i, t.columns, t.rows);
            const std::size_t node = geometry::grid_offset(i.column, i.row, t.columns);
            if (options.only_nodes && !large && only.count(node) == 0) continue;
            t.holes.push_back({i, t.node_mm(i), large, false});
        }
    if (options.only_nodes)
        for (std::size_t n : only) canonical += "|n" + std::to_string(n);
    if (router) {
        // Last, so that every hole before it was drilled with the slack taken up one way.
        const GridIndex middle{(t.columns - 1) / 2, (t.rows - 1) / 2};
        const geometry::Point2 at = t.node_mm(middle);
        t.backlash_hole =
            PlanarHole{middle, {at.x + 0.5 * t.pitch_mm, at.y + 0.5 * t.pitch_mm}, false, true};
        canonical += "|backlash";
    }
    t.fingerprint = models::digest(canonical);
    if (router) {
        auto holes = t.holes;
        holes.push_back(*t.backlash_hole);
        t.job = write_drilling_job(
            machine, holes, t.hole_diameter_mm, t.large_diameter_mm,
            "calbox planar target: " + std::to_string(t.columns) + " x " + std::to_string(t.rows) +
                " grid at " + number_text("%.3f", t.pitch_mm) + " mm, " +
                std::to_string(t.holes.size()) + " holes of " +
                number_text("%.3f", t.hole_diameter_mm) + " mm (two of " +
                number_text("%.3f", t.large_diameter_mm) + " mm), and one more for the backlash");
        return t;
    }
    t.job = printed_dots_job(t, machine, line_mm);
    return t;
}

}  // namespace calbox::targets
