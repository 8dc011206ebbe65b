#pragma once

// Where a cutter's offset paths go and meet, as LinuxCNC's cutter radius compensation finds
// them (its interp_convert.cc): angles in radians, turns 1 counter-clockwise and -1 clockwise.

#include <optional>
#include <string>

#include "core/geometry/types.hpp"

namespace calbox::jobs::cutter_geometry {

using geometry::Point2;

double angle_to(Point2 from, Point2 to);
Point2 toward(Point2 p, double length, double angle);

// The angle an arc about `centre` sweeps from `from` to `to`, going round counter-clockwise
// (turn 1, positive) or clockwise (-1, negative), a whole turn where it ends where it starts
// (LinuxCNC's find_turn).
double sweep_of(Point2 from, Point2 centre, int turn, Point2 to);

// A programmed arc's centre, as LinuxCNC's interpreter finds it (I J from the start; or R, the
// short way for R > 0), in the job's units (`unit_mm` mm each); `refused` says why LinuxCNC
// refuses the arc instead.
struct ArcCentre {
    Point2 centre;
    std::string refused;
};
ArcCentre programmed_arc_centre(Point2 start, Point2 end, int turn, std::optional<double> i,
                                std::optional<double> j, std::optional<double> r, bool k_given,
                                double unit_mm);

// The entry arc's centre: the cutter's arc runs from `from` (where the cutter is) to `end` (a
// radius off the programmed end), its centre on the line from `end` to the programmed `centre`;
// none where that line runs square to the chord.
std::optional<Point2> entry_arc_centre(Point2 from, Point2 end, Point2 centre);

// Where the cutter's path along a line (direction `line_angle`, turning by `corner_turn` into the
// arc) meets its path along the arc after it (about `centre`, `arc_radius` programmed), in an
// inside corner; none where they do not meet.
std::optional<Point2> line_meets_arc(double line_angle, double corner_turn, Point2 centre,
                                     double arc_radius, int turn, bool cutter_inside,
                                     double cutter_radius);

// Where the cutter's path along a held arc (about `held_centre`, `held_radius` the cutter's)
// meets its path along the next arc (about `centre`, `new_radius` the cutter's).
std::optional<Point2> arc_meets_arc(Point2 held_centre, double held_radius, bool held_inside,
                                    Point2 centre, double new_radius, int turn);

// Where the cutter's path along a held arc meets its path along the line from `corner` to `to`.
std::optional<Point2> arc_meets_line(Point2 held_centre, double held_radius, int held_turn,
                                     bool held_inside, Point2 corner, Point2 to,
                                     double cutter_radius);

}  // namespace calbox::jobs::cutter_geometry
