// The planar mode's solve: the quasi-static error model fitted to the measured holes, its
// bounds checked, and the command that lands the tool where it is meant.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/geometry/placement.hpp"
#include "core/modes/planar.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {

using geometry::Point2;

namespace {

// The backlash hole's slack: seen = R (c + e(c)) + t for a hole approached like the others; the
// rest is the slack, less what the model leaves unexplained there: the mean residual of the
// cell's four corner holes (the unexplained part changes slowly over a cell, the slack not at
// all).
Point2 backlash_of(const PlanarSolution& s, const PlanarMeasurement& measured) {
    const auto& hole = *measured.backlash_hole;
    const double c = std::cos(s.fit.rotation_rad), sn = std::sin(s.fit.rotation_rad);
    const double dx = hole.measured_mm.x - s.fit.translation_mm.x,
                 dy = hole.measured_mm.y - s.fit.translation_mm.y;
    const Point2 e = models::planar_error_mm(s.fit.parameters, hole.commanded_mm, s.tool_length_mm);
    Point2 local;
    int corners = 0;
    std::size_t k = 0;
    for (const auto& h : measured.holes) {
        if (h.large) continue;
        const int dc = h.index.column - hole.index.column, dr = h.index.row - hole.index.row;
        if ((dc == 0 || dc == 1) && (dr == 0 || dr == 1)) {
            local.x += s.fit.residuals_mm[k].x, local.y += s.fit.residuals_mm[k].y;
            ++corners;
        }
        ++k;
    }
    if (corners > 0) local = {local.x / corners, local.y / corners};
    return Point2{c * dx + sn * dy - hole.commanded_mm.x - e.x - local.x,
                  -sn * dx + c * dy - hole.commanded_mm.y - e.y - local.y};
}

// Bounds on what will be sent: the correction over the whole valid area, corners included.
void refuse_past_bounds(const PlanarSolution& s, const PlanarSolveOptions& options) {
    for (const Point2 corner : {Point2{s.min_x_mm, s.min_y_mm}, Point2{s.max_x_mm, s.min_y_mm},
                                Point2{s.min_x_mm, s.max_y_mm}, Point2{s.max_x_mm, s.max_y_mm}}) {
        const Point2 full = models::planar_error_mm(s.fit.parameters, corner, s.tool_length_mm);
        const Point2 rigid = s.rigid_part.at(corner);
        const Point2 e{full.x - rigid.x, full.y - rigid.y};
        if (!(std::hypot(e.x, e.y) <= options.max_error_mm))
            throw PlanarError("solve: the model's correction at X" + number_text("%.1f", corner.x) +
                              " Y" + number_text("%.1f", corner.y) + " is " +
                              number_text("%.2f", std::hypot(e.x, e.y)) +
                              " mm, beyond what a machine plausibly needs; nothing written");
    }
}

}  // namespace

PlanarSolution solve_planar(const models::MachineFile& machine, const PlanarMeasurement& measured,
                            const PlanarSolveOptions& options) {
    if (!machine.is_planar() || !machine.planar)
        throw PlanarError("solve: the machine is a " + machine.kind +
                          ", not a router, cartesian printer or laser");
    if (measured.machine_fingerprint != models::fingerprint(machine))
        throw PlanarError(
            "solve: the measurements were made for another machine file (fingerprint " +
            measured.machine_fingerprint + ")");
    const auto target = targets::make_planar_target(machine);
    if (measured.columns != target.columns || measured.rows != target.rows ||
        std::abs(measured.pitch_mm - target.pitch_mm) > 1e-9)
        throw PlanarError("solve: the measurements are of a " + std::to_string(measured.columns) +
                          " x " + std::to_string(measured.rows) +
                          " grid, this machine's target is " + std::to_string(target.columns) +
                          " x " + std::to_string(target.rows));
    PlanarSolution s;
    s.machine_fingerprint = measured.machine_fingerprint;
    s.frame = planar_frame_of(machine);
    s.tool_length_mm = machine.planar->tool_length_mm;
    std::vector<models::PlanarObservation> observations;
    std::vector<Point2> seen;
    double sigma2 = 0;
    s.min_x_mm = s.min_y_mm = 1e300;
    s.max_x_mm = s.max_y_mm = -1e300;
    for (const auto& hole : measured.holes) {
        // The large holes are widened by a circle that the drives' backlash bends: they say
        // which way round the grid lies, not where the tool plunged.
        if (hole.large) continue;
        observations.push_back({hole.commanded_mm, hole.measured_mm, hole.sigma_mm});
        s.commanded_mm.push_back(hole.commanded_mm);
        seen.push_back(hole.measured_mm);
        sigma2 += hole.sigma_mm * hole.sigma_mm;
        s.min_x_mm = std::min(s.min_x_mm, hole.commanded_mm.x);
        s.min_y_mm = std::min(s.min_y_mm, hole.commanded_mm.y);
        s.max_x_mm = std::max(s.max_x_mm, hole.commanded_mm.x);
        s.max_y_mm = std::max(s.max_y_mm, hole.commanded_mm.y);
    }
    if (observations.size() < 8)
        throw PlanarError("solve: " + std::to_string(observations.size()) +
                          " holes measured; the model needs at least 8");
    s.measurement_sigma_mm = std::sqrt(sigma2 / static_cast<double>(observations.size()));
    models::PlanarFitSettings fit_settings;
    fit_settings.abbe_height_mm = s.tool_length_mm;
    s.fit = models::fit_planar_errors(observations, fit_settings);
    s.bed_mirrored = measured.mirrored;
    // Before: what the holes show once only the machine's placement in the photo is taken out.
    const auto placement = geometry::best_rigid_placement(seen, s.commanded_mm);
    for (std::size_t i = 0; i < seen.size(); ++i) {
        const Point2 p = placement.apply(seen[i]);
        s.error_mm.push_back({p.x - s.commanded_mm[i].x, p.y - s.commanded_mm[i].y});
    }
    s.before = models::norm_statistics(s.error_mm);
    s.after = models::norm_statistics(s.fit.residuals_mm);
    if (s.before.max_mm > options.max_error_mm)
        throw PlanarError("solve: a hole lies " + number_text("%.2f", s.before.max_mm) +
                          " mm from where the machine was told to drill it, beyond the " +
                          number_text("%g", options.max_error_mm) +
                          " mm a machine out of calibration plausibly shows (check the pitch and "
                          "the photo); nothing written");
    if (measured.backlash_hole) s.backlash_mm = backlash_of(s, measured);
    s.rigid_part = models::rigid_part_of(s.fit.parameters, s.tool_length_mm, s.min_x_mm, s.min_y_mm,
                                         s.max_x_mm, s.max_y_mm);
    refuse_past_bounds(s, options);
    return s;
}

PlanarFrame planar_frame_of(const models::MachineFile& machine) {
    PlanarFrame f;
    f.work_zero_mm = {machine.work_zero_x_mm.value_or(0), machine.work_zero_y_mm.value_or(0)};
    f.work_zero_from = machine.work_zero_x_mm || machine.work_zero_y_mm
                           ? "the machine file"
                           : "the machine file (by default the machine's origin)";
    const auto travel = models::planar_travel_mm(machine);
    f.travel_min_x_mm = travel[0], f.travel_min_y_mm = travel[1];
    f.travel_max_x_mm = travel[2], f.travel_max_y_mm = travel[3];
    f.firmware = machine.firmware;
    f.kind = machine.kind;
    return f;
}

std::optional<Point2> grbl_work_zero_of(const std::vector<std::string>& replies,
                                        const std::string& system) {
    const std::string head = "[" + system + ":";
    for (const auto& reply : replies) {
        const auto at = reply.find(head);
        if (at == std::string::npos) continue;
        double x = 0, y = 0;
        char close = 0;
        if (std::sscanf(reply.c_str() + at + head.size(), "%lf,%lf,%*f%c", &x, &y, &close) == 3 &&
            close == ']' && std::isfinite(x) && std::isfinite(y))
            return Point2{x, y};
    }
    return std::nullopt;
}

Point2 planar_command_for(const PlanarSolution& s, Point2 intended_mm) {
    return models::planar_command_for(s.fit.parameters, intended_mm, s.tool_length_mm,
                                      s.rigid_part);
}

}  // namespace calbox::modes
