// A move's pieces (a line's, an arc's chords) and the correction each piece's end takes.
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "core/jobs/compensator.hpp"
#include "core/number_text.hpp"

namespace calbox::jobs::compensating {

std::vector<PathPoint> line_path(bool start_known, Point2 from, Point2 to,
                                 std::optional<double> z_from, std::optional<double> z_to,
                                 const CompensateSettings& settings) {
    const double length = start_known ? std::hypot(to.x - from.x, to.y - from.y) : 0;
    const int pieces = std::max(1, static_cast<int>(std::ceil(length / settings.max_segment_mm)));
    std::vector<PathPoint> path;
    for (int k = 1; k <= pieces; ++k) {
        const double share = static_cast<double>(k) / pieces;
        std::optional<double> z = z_to;
        if (z_from && z_to) z = *z_from + (*z_to - *z_from) * share;
        path.push_back({k == pieces ? to
                                    : Point2{from.x + (to.x - from.x) * share,
                                             from.y + (to.y - from.y) * share},
                        z});
    }
    return path;
}

namespace {

// The arc's centre in its plane's coordinates (a, b): from R (clockwise with R > 0 the short
// way) or from its offsets (I J, K I or J K by the plane).
std::array<double, 2> arc_centre(const gcode::Line& line, const Modal& m,
                                 const std::array<double, 3>& f, const std::array<double, 3>& t,
                                 double r_tolerance_mm, const Failure& fail) {
    const char offset_a = m.plane == 17 ? 'I' : (m.plane == 18 ? 'K' : 'J');
    const char offset_b = m.plane == 17 ? 'J' : (m.plane == 18 ? 'I' : 'K');
    const bool clockwise = m.motion == 2;
    double ca = 0, cb = 0;
    if (line.has('R')) {
        const double r = line.value('R').value_or(0) * m.unit_mm;
        const double da = t[0] - f[0], db = t[1] - f[1], chord = std::hypot(da, db);
        if (chord == 0)
            throw fail(
                "an R arc that ends where it starts: its centre is not defined (write it "
                "with I J K)");
        // Short by no more than the file's written precision, it is the half circle its rounding
        // hid, as LinuxCNC and Mach3 cut it.
        const double shortfall = chord / 2 - std::abs(r);
        if (!(shortfall <= r_tolerance_mm))
            throw fail("an R arc no controller could cut: radius " + number(std::abs(r), 5) +
                       " mm, chord " + number(chord, 5) + " mm, so R is " + number(shortfall, 5) +
                       " mm short of half the chord, past the file's written precision of " +
                       number(r_tolerance_mm, 6) + " mm; have the CAM write the arc again");
        const double h = std::sqrt(std::max(0.0, r * r - chord * chord / 4));
        // Clockwise with R > 0 takes the short way: the centre to the chord's right.
        const double side = (clockwise ? 1 : -1) * (r > 0 ? 1 : -1);
        ca = f[0] + da / 2 + side * h * db / chord;
        cb = f[1] + db / 2 - side * h * da / chord;
    } else {
        if (!line.has(offset_a) && !line.has(offset_b))
            throw fail(std::string("an arc needs ") + offset_a + " and " + offset_b + ", or R");
        ca = f[0] + line.value(offset_a).value_or(0) * m.unit_mm;
        cb = f[1] + line.value(offset_b).value_or(0) * m.unit_mm;
    }
    return {ca, cb};
}

}  // namespace

std::vector<PathPoint> arc_path(const gcode::Line& line, const Modal& m, Point2 from, Point2 to,
                                std::optional<double> z_from, std::optional<double> z_to,
                                const CompensateSettings& settings, double r_tolerance_mm,
                                const Failure& fail) {
    if (!m.xy_known) throw fail("an arc needs a known start");
    if (m.plane != 17 && (!z_from || !z_to))
        throw fail("an arc in the XZ or YZ plane needs a known Z");
    // The arc's plane as (a, b) with the helix along h: G17 XY, G18 ZX, G19 YZ, each ordered so
    // that a x b is the plane's normal (clockwise as seen from its positive side).
    const auto to_abh = [&](Point2 xy, double z) -> std::array<double, 3> {
        if (m.plane == 18) return {z, xy.x, xy.y};
        if (m.plane == 19) return {xy.y, z, xy.x};
        return {xy.x, xy.y, z};
    };
    const auto from_abh = [&](const std::array<double, 3>& p) -> PathPoint {
        if (m.plane == 18) return {{p[1], p[2]}, p[0]};
        if (m.plane == 19) return {{p[2], p[0]}, p[1]};
        return {{p[0], p[1]}, p[2]};
    };
    const auto f = to_abh(from, z_from.value_or(0));
    const auto t = to_abh(to, z_to.value_or(0));
    const bool clockwise = m.motion == 2;
    const auto [ca, cb] = arc_centre(line, m, f, t, r_tolerance_mm, fail);
    const double radius = std::hypot(f[0] - ca, f[1] - cb);
    const double end_radius = std::hypot(t[0] - ca, t[1] - cb);
    // LinuxCNC's own bound on a centre-format arc whose end is off the start's circle: past
    // both, it refuses the arc, and so does calbox.
    const double radius_step = std::abs(end_radius - radius);
    if (job_words::arc_end_off_its_circle(radius, radius_step, m.unit_mm > 1))
        throw fail("an arc no controller could cut: its end is " + number(radius_step, 5) +
                   " mm off the circle through its start (radius " + number(radius, 5) +
                   " mm about its centre); have the CAM write the arc again");
    const double a0 = std::atan2(f[1] - cb, f[0] - ca);
    const double a1 = std::atan2(t[1] - cb, t[0] - ca);
    double sweep = a1 - a0;
    if (clockwise) {
        while (sweep >= -1e-12) sweep -= 2 * std::numbers::pi;
    } else {
        while (sweep <= 1e-12) sweep += 2 * std::numbers::pi;
    }
    if (std::hypot(t[0] - f[0], t[1] - f[1]) < 1e-9 && !line.has('R'))
        sweep = clockwise ? -2 * std::numbers::pi : 2 * std::numbers::pi;  // a whole circle
    // LinuxCNC's P: the arc goes round P times (P - 1 whole turns more).
    if (const auto turns = line.value('P')) {
        if (!(*turns >= 1 && *turns <= 1000 && *turns == std::floor(*turns)))
            throw fail("an arc's P (its turns) is a whole number from 1 to 1000, not " +
                       number(*turns, 4));
        sweep += (clockwise ? -2 * std::numbers::pi : 2 * std::numbers::pi) * (*turns - 1);
    }
    const double by_tolerance = radius > settings.arc_tolerance_mm
                                    ? 2 * std::acos(1 - settings.arc_tolerance_mm / radius)
                                    : std::numbers::pi;
    const double by_length = settings.max_segment_mm / std::max(radius, 1e-9);
    const int pieces = std::max(
        1, static_cast<int>(std::ceil(std::abs(sweep) / std::min(by_tolerance, by_length))));
    std::vector<PathPoint> path;
    for (int k = 1; k <= pieces; ++k) {
        if (k == pieces) {
            path.push_back({to, z_to});
            continue;
        }
        const double a = a0 + sweep * k / pieces;
        const double share = static_cast<double>(k) / pieces;
        // CAM rounds I J K: the end lies a micron or so off the start's circle. The radius moves
        // from the start's to the end's along the sweep, so the path meets the end without a step.
        const double r = radius + (end_radius - radius) * share;
        PathPoint p =
            from_abh({ca + r * std::cos(a), cb + r * std::sin(a), f[2] + (t[2] - f[2]) * share});
        if (m.plane == 17 && !(z_from && z_to)) p.z_mm = z_to;
        path.push_back(p);
    }
    return path;
}

Point2 held_correction(const MachineCorrection& correction, Point2 p, CompensateReport& report) {
    if (report.keep_path) report.path_mm.push_back(p);
    const auto& area = correction.measured_mm;
    if (area.contains(p)) return correction.correct(p);
    const Point2 q = area.nearest(p);
    const Point2 c = correction.correct(q);
    ++report.held;
    report.held_farthest_mm = std::max(report.held_farthest_mm, std::hypot(p.x - q.x, p.y - q.y));
    return {p.x + c.x - q.x, p.y + c.y - q.y};
}

}  // namespace calbox::jobs::compensating
