#pragma once
// The tests' own reading of G-code motion, kept apart from the compensator it judges: each
// move's XY path (the frame without G92 offsets, mm), arcs sampled finely in their plane. It
// reads what slicers, CAM and calbox itself write: G0-G3 (modal), G17/G18/G19, G20/G21,
// G90/G91, G92/G92.1, G28 (position forgotten), comments, N and checksums.
#include <cmath>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/gcode/gcode_line.hpp"

namespace calbox::test {

struct ReferenceMove {
    std::vector<geometry::Point2> path_mm;  // from the start (included) to the end
    bool start_known = true;                // false for the first move and the first after G28
};

inline std::vector<ReferenceMove> reference_motion(const std::string& job) {
    std::vector<ReferenceMove> moves;
    int motion = -1, plane = 17;
    bool absolute = true;
    double unit = 1;
    geometry::Point2 at, offset;
    double z = 0;
    bool known = false;
    std::istringstream in(job);
    for (std::string raw; std::getline(in, raw);) {
        const auto line = gcode::parse_line(raw);
        std::vector<double> g;
        if (line.command_letter == 'G')
            g.push_back(line.command_number +
                        (line.command_subcode > 0 ? line.command_subcode / 10.0 : 0));
        for (const auto& w : line.parameters)
            if (w.letter == 'G' && w.value) g.push_back(*w.value);
        bool not_a_move = line.command_letter == 'M' || line.command_letter == 'T';
        for (const double c : g) {
            if (c == 0 || c == 1 || c == 2 || c == 3) motion = static_cast<int>(c);
            if (c == 17 || c == 18 || c == 19) plane = static_cast<int>(c);
            if (c == 20) unit = 25.4;
            if (c == 21) unit = 1;
            if (c == 90) absolute = true;
            if (c == 91) absolute = false;
            if (c == 80) motion = -1;
            if (std::abs(c - 92.1) < 1e-9) offset = {}, not_a_move = true;
            if (c == 28 || c == 30) known = false, not_a_move = true;
            if (c == 4 || c == 53 || c == 10) not_a_move = true;
            if (c == 92) {
                not_a_move = true;
                if (auto x = line.value('X')) offset.x = at.x - *x * unit;
                if (auto y = line.value('Y')) offset.y = at.y - *y * unit;
                if (auto zz = line.value('Z')) z = *zz * unit;
            }
        }
        if (not_a_move || motion < 0) continue;
        const bool arc = motion == 2 || motion == 3;
        if (!(line.has('X') || line.has('Y') || line.has('Z') ||
              (arc && (line.has('I') || line.has('J') || line.has('K') || line.has('R')))))
            continue;
        geometry::Point2 to = at;
        if (auto x = line.value('X')) to.x = absolute ? *x * unit + offset.x : at.x + *x * unit;
        if (auto y = line.value('Y')) to.y = absolute ? *y * unit + offset.y : at.y + *y * unit;
        double z_to = z;
        if (auto zz = line.value('Z')) z_to = absolute ? *zz * unit : z + *zz * unit;
        if (!(line.has('X') || line.has('Y') || arc)) {
            z = z_to;
            continue;
        }
        ReferenceMove move;
        move.start_known = known;
        move.path_mm.push_back(at);
        if (!arc || !known) {
            move.path_mm.push_back(to);
        } else {
            // The plane's two axes (a, b), in the standard's order for each plane.
            const auto a_of = [&](geometry::Point2 p, double h) {
                return plane == 17 ? p.x : plane == 18 ? h : p.y;
            };
            const auto b_of = [&](geometry::Point2 p, double h) {
                return plane == 17 ? p.y : plane == 18 ? p.x : h;
            };
            const double fa = a_of(at, z), fb = b_of(at, z), ta = a_of(to, z_to),
                         tb = b_of(to, z_to);
            double ca = 0, cb = 0;
            if (auto r = line.value('R')) {
                const double rr = *r * unit, da = ta - fa, db = tb - fb, chord = std::hypot(da, db);
                const double h = std::sqrt(std::max(0.0, rr * rr - chord * chord / 4));
                const double side = (motion == 2 ? 1 : -1) * (rr > 0 ? 1 : -1);
                ca = fa + da / 2 + side * h * db / chord;
                cb = fb + db / 2 - side * h * da / chord;
            } else {
                const char ka = plane == 17 ? 'I' : plane == 18 ? 'K' : 'J';
                const char kb = plane == 17 ? 'J' : plane == 18 ? 'I' : 'K';
                ca = fa + line.value(ka).value_or(0) * unit;
                cb = fb + line.value(kb).value_or(0) * unit;
            }
            const double radius = std::hypot(fa - ca, fb - cb);
            const double end_radius = std::hypot(ta - ca, tb - cb);  // rounded I J: a spiral
            const double a0 = std::atan2(fb - cb, fa - ca), a1 = std::atan2(tb - cb, ta - ca);
            double sweep = a1 - a0;
            const double turn = 2 * 3.14159265358979323846;
            if (motion == 2) {
                while (sweep >= -1e-12) sweep -= turn;
            } else {
                while (sweep <= 1e-12) sweep += turn;
            }
            if (std::hypot(ta - fa, tb - fb) < 1e-9 && !line.has('R'))
                sweep = motion == 2 ? -turn : turn;
            // Samples 0.0002 mm at most off the arc.
            const int n = std::max(
                2, static_cast<int>(std::ceil(std::abs(sweep) * radius /
                                              std::sqrt(8 * 0.0002 * std::max(radius, 1e-6)))));
            for (int k = 1; k <= n; ++k) {
                const double s = static_cast<double>(k) / n, t = a0 + sweep * s;
                const double rs = radius + (end_radius - radius) * s;
                const double pa = ca + rs * std::cos(t), pb = cb + rs * std::sin(t);
                const double h = (plane == 17   ? z
                                  : plane == 18 ? at.y
                                                : at.x) +
                                 ((plane == 17   ? z_to
                                   : plane == 18 ? to.y
                                                 : to.x) -
                                  (plane == 17   ? z
                                   : plane == 18 ? at.y
                                                 : at.x)) *
                                     s;
                geometry::Point2 p = plane == 17   ? geometry::Point2{pa, pb}
                                     : plane == 18 ? geometry::Point2{pb, h}
                                                   : geometry::Point2{h, pa};
                move.path_mm.push_back(k == n ? to : p);
            }
        }
        known = true;
        at = to;
        z = z_to;
        moves.push_back(std::move(move));
    }
    return moves;
}

}  // namespace calbox::test
