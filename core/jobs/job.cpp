#include "core/jobs/job.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>

#include "core/number_text.hpp"

namespace calbox::jobs {
using drawings::Contour;
using drawings::FillRule;
using drawings::intersect_lines;
using drawings::intersect_region;
using drawings::Polygon;
using drawings::resolve_fill;
using drawings::SvgDocument;
using drawings::SvgShape;
namespace {

using geometry::Point2;

double line_width_of(const models::MachineFile& m) {
    return m.is_printer() ? m.line_width_mm : m.tool_width_mm;
}

std::string spaced_xy(Point2 p) {
    return " X" + fixed_text(p.x, 4) + " Y" + fixed_text(p.y, 4);
}

// The drawing as a browser shows it: a shape shows only inside its clip path, and what lies past
// the page (the viewport the document's width, height and viewBox make) is not shown, so each
// shape reaching past either is cut at its edge, its fill as a region and its stroke as lines.
// Whether every point of the shape lies on a w x h page. A point within a micrometre of the page
// is on it: librsvg's painting (through cairo's fixed point) gives a corner on the page's edge
// back a fraction of that off it.
bool lies_on_page(const SvgShape& shape, double w, double h) {
    constexpr double kOnEdgeMm = 0.001;
    for (const auto& c : shape.contours)
        for (const auto& p : c.points)
            if (!(p.x >= -kOnEdgeMm && p.x <= w + kOnEdgeMm && p.y >= -kOnEdgeMm &&
                  p.y <= h + kOnEdgeMm))
                return false;
    return true;
}

// What of the shape shows through `window`: its fill (its rule resolved) and its stroke, each a
// shape of its own.
void add_shown_parts(const SvgShape& shape, const std::vector<Polygon>& window,
                     std::optional<FillRule> fill_rule, SvgDocument& shown) {
    if (shape.filled) {
        SvgShape fill = shape;
        fill.stroked = false;
        fill.clip_region.reset();
        fill.fill_rule = FillRule::nonzero;  // resolved below
        fill.contours.clear();
        for (auto& p : intersect_region(
                 resolve_fill(shape.contours, fill_rule.value_or(shape.fill_rule)), window))
            fill.contours.push_back({std::move(p), true});
        if (!fill.contours.empty()) shown.shapes.push_back(std::move(fill));
    }
    if (shape.stroked) {
        SvgShape stroke = shape;
        stroke.filled = false;
        stroke.clip_region.reset();
        stroke.contours = intersect_lines(shape.contours, window);
        if (!stroke.contours.empty()) shown.shapes.push_back(std::move(stroke));
    }
}

SvgDocument cut_to_shown(const SvgDocument& document, std::optional<FillRule> fill_rule,
                         int& shapes_cut_at_page) {
    const double w = document.width_mm, h = document.height_mm;
    const bool has_page = w > 0 && h > 0;
    SvgDocument shown = document;
    shown.shapes.clear();
    const std::vector<Polygon> page{{{0, 0}, {w, 0}, {w, h}, {0, h}}};
    for (const auto& shape : document.shapes) {
        const bool within = !has_page || lies_on_page(shape, w, h);
        if (within && !shape.clip_region) {
            shown.shapes.push_back(shape);
            continue;
        }
        if (!within) ++shapes_cut_at_page;
        std::vector<Polygon> window = has_page ? page : std::vector<Polygon>{};
        if (shape.clip_region)
            window = has_page ? intersect_region(*shape.clip_region, page) : *shape.clip_region;
        add_shown_parts(shape, window, fill_rule, shown);
    }
    return shown;
}

}  // namespace

double checked_spacing_mm(const models::MachineFile& machine, std::optional<double> spacing_mm) {
    const double w = line_width_of(machine);
    const double lo = machine.is_printer() ? w : 0.01, hi = machine.is_printer() ? 10 * w : 10.0;
    const double s = spacing_mm.value_or(w);
    if (!(s >= lo - 1e-12 && s <= hi + 1e-12)) {
        throw JobError("spacing " + number_text("%g", s) + " mm is outside the valid range " +
                       number_text("%g", lo) + " to " + number_text("%g", hi) + " mm for this " +
                       machine.kind +
                       (machine.is_printer()
                            ? " (at least its line width, " + number_text("%g", w) + " mm)"
                            : ""));
    }
    return s;
}

double PlacedJob::estimated_time_s(const models::MachineFile& machine) const {
    return toolpath.working_length_mm() / feed_mm_s +
           toolpath.travel_length_mm() / machine.travel_feed_mm_s;
}

namespace {

// The placed drawing refused where it leaves what the machine reaches, in a line naming the
// region and the largest --fit that makes it fit; `w` x `h` is the drawing's own extent.
void refuse_unless_it_fits(const PlacedJob& job, const models::MachineFile& machine, double w,
                           double h) {
    // Where the drawing must lie, whether it does, and the largest scale at which the centred
    // drawing would.
    bool fits = false;
    std::string region;
    double largest_scale = 0;
    if (machine.is_delta()) {
        fits =
            std::hypot(std::max(std::abs(job.min_x), std::abs(job.max_x)),
                       std::max(std::abs(job.min_y), std::abs(job.max_y))) <= machine.bed_radius_mm;
        region = "the bed (a circle of " + fixed_text(machine.bed_radius_mm, 1) + " mm radius)";
        largest_scale = machine.bed_radius_mm / std::hypot(w / 2, h / 2);
    } else if (machine.is_galvo()) {
        const double half_field = machine.galvo ? machine.galvo->field_size_mm / 2 : 0;
        fits = job.min_x >= -half_field && job.min_y >= -half_field && job.max_x <= half_field &&
               job.max_y <= half_field;
        region = "the scanner's field (" + fixed_text(2 * half_field, 1) + " x " +
                 fixed_text(2 * half_field, 1) + " mm)";
        largest_scale = std::min(2 * half_field / w, 2 * half_field / h);
    } else {
        fits = job.min_x >= 0 && job.min_y >= 0 && job.max_x <= machine.bed_size_x_mm &&
               job.max_y <= machine.bed_size_y_mm;
        region = "the bed (" + fixed_text(machine.bed_size_x_mm, 1) + " x " +
                 fixed_text(machine.bed_size_y_mm, 1) + " mm)";
        largest_scale = std::min(machine.bed_size_x_mm / w, machine.bed_size_y_mm / h);
    }
    if (!fits) {
        // As the --fit that gives it, rounded down to 0.1 mm so that it does fit.
        const double largest_fit_mm = std::floor(largest_scale * std::max(w, h) * 10 - 1e-9) / 10;
        throw JobError("the drawing, " + fixed_text(job.max_x - job.min_x, 1) + " x " +
                       fixed_text(job.max_y - job.min_y, 1) + " mm at scale " +
                       number_text("%g", job.scale) + ", does not fit " + region + "; --fit " +
                       fixed_text(largest_fit_mm, 1) +
                       " (its larger side in mm) or less makes it fit");
    }
}

}  // namespace

namespace {

struct DrawingExtent {
    double xmin, ymin, xmax, ymax;
};
// The box around every point of the shapes, in the drawing's millimetres.
DrawingExtent extent_of(const SvgDocument& shown) {
    double xmin = std::numeric_limits<double>::infinity(), ymin = xmin, xmax = -xmin, ymax = -xmin;
    for (const auto& shape : shown.shapes)
        for (const auto& c : shape.contours)
            for (const auto& p : c.points)
                xmin = std::min(xmin, p.x), xmax = std::max(xmax, p.x), ymin = std::min(ymin, p.y),
                ymax = std::max(ymax, p.y);
    return {xmin, ymin, xmax, ymax};
}

// The scale --fit (the larger side's length) or --scale asks for; nothing when neither is given.
std::optional<double> scale_asked(const SvgJobSettings& settings, double larger_side_mm) {
    if (settings.fit_mm) {
        if (!(*settings.fit_mm > 0)) throw JobError("--fit must be a positive length");
        return *settings.fit_mm / larger_side_mm;
    }
    if (settings.scale) {
        if (!(*settings.scale > 0)) throw JobError("--scale must be positive");
        return *settings.scale;
    }
    return std::nullopt;
}

}  // namespace

PlacedJob plan_svg_job(const SvgDocument& document, const models::MachineFile& machine,
                       const SvgJobSettings& settings) {
    PlacedJob job;
    job.line_width_mm = line_width_of(machine);
    job.spacing_mm = checked_spacing_mm(machine, settings.spacing_mm);
    job.feed_mm_s = settings.feed_mm_s.value_or(machine.feed_mm_s);
    if (!(job.feed_mm_s > 0 && job.feed_mm_s <= 2000))
        throw JobError("feed must be between 0 and 2000 mm/s");
    if (settings.perimeters < 0 || settings.perimeters > 20)
        throw JobError("perimeters must be 0 to 20");
    if (settings.scale && settings.fit_mm) throw JobError("give --scale or --fit, not both");
    const SvgDocument shown = cut_to_shown(document, settings.fill_rule, job.shapes_cut_at_page);
    if (shown.shapes.empty()) throw JobError("nothing of the drawing lies on its page");
    const auto [xmin, ymin, xmax, ymax] = extent_of(shown);
    const double larger = std::max(xmax - xmin, ymax - ymin);
    if (!(larger > 0)) throw JobError("the drawing has no extent");
    if (const auto scale = scale_asked(settings, larger)) job.scale = *scale;
    // Centred on the bed (a delta's and a galvo's origin is the middle of their area); SVG's y
    // runs down the page, the machine's up the bed.
    const Point2 bed_centre = machine.is_delta() || machine.is_galvo()
                                  ? Point2{0, 0}
                                  : Point2{machine.bed_size_x_mm / 2, machine.bed_size_y_mm / 2};
    const double cx = (xmin + xmax) / 2, cy = (ymin + ymax) / 2;
    const auto place = [&](Point2 p) {
        return Point2{bed_centre.x + (p.x - cx) * job.scale, bed_centre.y - (p.y - cy) * job.scale};
    };
    job.drawing_min = {xmin, ymin};
    job.min_x = bed_centre.x - (xmax - xmin) / 2 * job.scale;
    job.max_x = bed_centre.x + (xmax - xmin) / 2 * job.scale;
    job.min_y = bed_centre.y - (ymax - ymin) / 2 * job.scale;
    job.max_y = bed_centre.y + (ymax - ymin) / 2 * job.scale;
    refuse_unless_it_fits(job, machine, xmax - xmin, ymax - ymin);
    FillSettings fill;
    fill.line_width_mm = job.line_width_mm;
    fill.spacing_mm = job.spacing_mm;
    fill.angle_deg = settings.angle_deg;
    fill.perimeters = settings.perimeters;
    Point2 pen = bed_centre;
    for (const auto& shape : shown.shapes) {
        std::vector<Contour> placed;
        for (const auto& c : shape.contours) {
            Contour p{{}, c.closed};
            std::transform(c.points.begin(), c.points.end(), std::back_inserter(p.points), place);
            placed.push_back(std::move(p));
        }
        // As a browser paints it: the fill (nothing where it has no area), then the stroke
        // over it, traced along its centreline.
        if (shape.filled)
            append(job.toolpath,
                   plan_fill(placed, settings.fill_rule.value_or(shape.fill_rule), fill, pen));
        if (shape.stroked) append(job.toolpath, plan_trace(placed, pen));
    }
    if (job.toolpath.working_length_mm() <= 0)
        throw JobError("the drawing is too small to fill with a " +
                       number_text("%g", job.line_width_mm) + " mm line");
    return job;
}

namespace {

// A printer's job: heated, homed, filament measured along each line, lifted over the print.
// The printer's own start or end G-code, or calbox's: heat and home; cool and release.
void printer_start_lines(std::string& out, const models::MachineFile& m) {
    if (m.start_gcode) {
        out += *m.start_gcode;
        if (!out.empty() && out.back() != '\n') out += "\n";
        return;
    }
    if (m.bed_temperature_c) out += "M190 S" + fixed_text(*m.bed_temperature_c, 0) + "\n";
    if (m.nozzle_temperature_c) out += "M109 S" + fixed_text(*m.nozzle_temperature_c, 0) + "\n";
    out += "G28\n";
}

void printer_end_lines(std::string& out, const models::MachineFile& m) {
    if (m.end_gcode) {
        out += *m.end_gcode;
        if (!out.empty() && out.back() != '\n') out += "\n";
        return;
    }
    if (m.nozzle_temperature_c) out += "M104 S0\n";
    if (m.bed_temperature_c) out += "M140 S0\n";
    out += "M84\n";
}

// One layer of the toolpath at height z, the extruder's E running on from `e`.
void printer_layer_lines(std::string& out, const PlacedJob& job, const models::MachineFile& m,
                         int layer, double e_per_mm, double& e) {
    const auto line = [&](const std::string& text) { out += text + "\n"; };
    const double feed = job.feed_mm_s * 60, travel = m.travel_feed_mm_s * 60;
    const double z = layer * m.layer_height_mm, hop = z + 0.4;
    if (layer > 1) line("G0 Z" + fixed_text(hop, 3));
    bool lifted = true;
    for (const auto& move : job.toolpath.moves) {
        if (move.kind == MoveKind::travel) {
            // Lift over the print for anything longer than a hop to the next line.
            if (move.length_mm() > 2 * job.spacing_mm && !lifted) {
                line("G0 Z" + fixed_text(hop, 3));
                lifted = true;
            }
            line("G0" + spaced_xy(move.to) + " F" + fixed_text(travel, 0));
            continue;
        }
        if (lifted) {
            line("G0 Z" + fixed_text(z, 3));
            lifted = false;
        }
        e += move.length_mm() * e_per_mm;
        line("G1" + spaced_xy(move.to) + " E" + fixed_text(e, 5) + " F" + fixed_text(feed, 0));
    }
}

void printer_job_lines(std::string& out, const PlacedJob& job, const models::MachineFile& m) {
    const double travel = m.travel_feed_mm_s * 60;
    out += "M82\n";
    printer_start_lines(out, m);
    out += "G92 E0\n";
    const double e_per_mm =
        job.line_width_mm * m.layer_height_mm /
        (3.14159265358979323846 * m.filament_diameter_mm * m.filament_diameter_mm / 4);
    double e = 0;
    out += "G0 Z" + fixed_text(m.safe_height_mm, 3) + " F" + fixed_text(travel, 0) + "\n";
    for (int layer = 1; layer <= job.layers; ++layer)
        printer_layer_lines(out, job, m, layer, e_per_mm, e);
    out += "G0 Z" + fixed_text(m.safe_height_mm + 10, 3) + " F" + fixed_text(travel, 0) + "\n";
    printer_end_lines(out, m);
}

// A router's or a laser's job: the spindle or the beam on only while working.
void machine_job_lines(std::string& out, const PlacedJob& job, const models::MachineFile& m) {
    const auto line = [&](const std::string& text) { out += text + "\n"; };
    const double feed = job.feed_mm_s * 60, travel = m.travel_feed_mm_s * 60;
    const bool router = m.tool() == models::MachineTool::spindle;
    const double power_scale = m.firmware == "grbl" ? 1000 : 255;
    line("M5");
    if (router) {
        line("G0 Z" + fixed_text(m.safe_height_mm, 3) + " F" + fixed_text(travel, 0));
        line("M3 S" + fixed_text(m.spindle_rpm, 0));
    }
    bool working = false;
    for (const auto& move : job.toolpath.moves) {
        if (move.kind == MoveKind::travel) {
            if (working) line(router ? "G0 Z" + fixed_text(m.safe_height_mm, 3) : "M5");
            working = false;
            line("G0" + spaced_xy(move.to) + " F" + fixed_text(travel, 0));
            continue;
        }
        if (!working) {
            line(router ? "G1 Z" + fixed_text(-m.cut_depth_mm, 3) + " F" + fixed_text(feed / 4, 0)
                        : "M3 S" + fixed_text(m.laser_power * power_scale, 0));
            working = true;
        }
        line("G1" + spaced_xy(move.to) + " F" + fixed_text(feed, 0));
    }
    if (router) line("G0 Z" + fixed_text(m.safe_height_mm, 3));
    line("M5");
}

}  // namespace

std::string write_gcode(const PlacedJob& job, const models::MachineFile& m,
                        const std::string& title) {
    std::string out;
    const auto line = [&](const std::string& text) { out += text + "\n"; };
    line("; " + title);
    line("; calbox job for a " + m.kind + " (" + m.firmware + "): line " +
         number_text("%g", job.line_width_mm) + " mm, spacing " +
         number_text("%g", job.spacing_mm) + " mm, " +
         fixed_text(job.toolpath.working_length_mm(), 1) + " mm of path");
    line("G21");
    line("G90");
    if (m.is_printer())
        printer_job_lines(out, job, m);
    else
        machine_job_lines(out, job, m);
    return out;
}

}  // namespace calbox::jobs
