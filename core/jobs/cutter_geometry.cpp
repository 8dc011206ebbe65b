#include "core/jobs/cutter_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/jobs/job_words.hpp"

namespace calbox::jobs::cutter_geometry {
namespace {

using std::numbers::pi;
constexpr double kHalfPi = pi / 2;

// LinuxCNC's RADIUS_TOLERANCE in mm (0.00005 inch): how far an R arc may fall short of its end.
constexpr double kRadiusToleranceMm = 0.00005 * 25.4;

// A sine or cosine the paths' meeting needs: beyond 1 they do not meet.
bool reachable(double share) {
    return share <= 1 && share >= -1;
}

}  // namespace

double angle_to(Point2 from, Point2 to) {
    return std::atan2(to.y - from.y, to.x - from.x);
}

Point2 toward(Point2 p, double length, double angle) {
    return {p.x + length * std::cos(angle), p.y + length * std::sin(angle)};
}

double sweep_of(Point2 from, Point2 centre, int turn, Point2 to) {
    double a = angle_to(centre, from), b = angle_to(centre, to);
    if (turn > 0) {
        if (b <= a) b += 2 * pi;
        return b - a;
    }
    if (a <= b) a += 2 * pi;
    return b - a;
}

ArcCentre programmed_arc_centre(Point2 start, Point2 end, int turn, std::optional<double> i,
                                std::optional<double> j, std::optional<double> r, bool k_given,
                                double unit_mm) {
    using job_words::number;
    if (r && (i || j || k_given))
        return {{}, "an arc given both by its radius (R) and its centre (I, J, K)"};
    if (r) {
        if (start.x == end.x && start.y == end.y)
            return {{}, "an R arc that ends where it starts: its centre is not defined"};
        const double radius = std::abs(*r);
        const Point2 middle{(start.x + end.x) / 2, (start.y + end.y) / 2};
        double half_chord = geometry::distance(middle, end);
        if (half_chord - radius > kRadiusToleranceMm / unit_mm)
            return {{},
                    "an R arc whose radius " + number(radius, 4) +
                        " does not reach its end (half its chord is " + number(half_chord, 4) +
                        ")"};
        half_chord = std::min(half_chord, radius);
        const double side = (turn < 0) == (*r > 0) ? -kHalfPi : kHalfPi;
        const double offset = radius * std::cos(std::asin(half_chord / radius));
        return {toward(middle, offset, angle_to(start, end) + side), {}};
    }
    const Point2 centre{start.x + i.value_or(0), start.y + j.value_or(0)};
    const double radius = geometry::distance(centre, start);
    const double end_radius = geometry::distance(centre, end);
    if (radius * unit_mm < 1e-6 || end_radius * unit_mm < 1e-6) return {{}, "an arc of radius 0"};
    if (job_words::arc_end_off_its_circle(radius * unit_mm, std::abs(end_radius - radius) * unit_mm,
                                          unit_mm > 1))
        return {{},
                "an arc whose end is " + number(std::abs(end_radius - radius), 5) +
                    " off the circle through its start"};
    return {centre, {}};
}

std::optional<Point2> entry_arc_centre(Point2 from, Point2 end, Point2 centre) {
    const double to_centre = angle_to(end, centre);
    const double corner = angle_to(end, from) - to_centre;
    if (std::abs(std::cos(corner)) < 1e-4) return std::nullopt;  // LinuxCNC's TOLERANCE_EQUAL
    return toward(end, geometry::distance(from, end) / 2 / std::cos(corner), to_centre);
}

std::optional<Point2> line_meets_arc(double line_angle, double corner_turn, Point2 centre,
                                     double arc_radius, int turn, bool cutter_inside,
                                     double cutter_radius) {
    const double across = arc_radius * std::sin(corner_turn - kHalfPi);
    if (cutter_inside) {
        const double reach = arc_radius - cutter_radius;
        const double share = (across + cutter_radius) / reach;
        if (!reachable(share)) return std::nullopt;
        return toward(centre, reach,
                      turn > 0 ? line_angle + std::asin(share) : line_angle - std::asin(share));
    }
    const double reach = arc_radius + cutter_radius;
    const double share = (across - cutter_radius) / reach;
    if (!reachable(share)) return std::nullopt;
    return toward(
        centre, reach,
        turn > 0 ? line_angle + pi - std::asin(share) : line_angle + pi + std::asin(share));
}

std::optional<Point2> arc_meets_arc(Point2 held_centre, double held_radius, bool held_inside,
                                    Point2 centre, double new_radius, int turn) {
    const double between = geometry::distance(held_centre, centre);
    const double cosine =
        (held_radius * held_radius + between * between - new_radius * new_radius) /
        (2 * held_radius * between);
    if (!reachable(cosine)) return std::nullopt;
    const double pull = std::acos(cosine);
    const double across = angle_to(held_centre, centre);
    const bool plus = held_inside == (turn > 0);
    return toward(held_centre, held_radius, plus ? across + pull : across - pull);
}

std::optional<Point2> arc_meets_line(Point2 held_centre, double held_radius, int held_turn,
                                     bool held_inside, Point2 corner, Point2 to,
                                     double cutter_radius) {
    const double normal = angle_to(corner, to) + (held_turn > 0 ? kHalfPi : -kHalfPi);
    const double programmed_radius =
        held_inside ? held_radius + cutter_radius : held_radius - cutter_radius;
    const double across = programmed_radius * std::cos(normal - angle_to(corner, held_centre));
    const double share =
        (held_inside ? across - cutter_radius : across + cutter_radius) / held_radius;
    if (!reachable(share)) return std::nullopt;
    const bool minus = held_inside == (held_turn > 0);
    return toward(held_centre, held_radius,
                  (minus ? -std::acos(share) : std::acos(share)) + normal + pi);
}

}  // namespace calbox::jobs::cutter_geometry
