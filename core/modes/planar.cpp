#include "core/modes/planar.hpp"

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <algorithm>
#include <cmath>
#include <map>

#include "core/modes/json_file.hpp"
#include "core/modes/mark_grid.hpp"
#include "core/number_text.hpp"
#include "core/solve/placement.hpp"

namespace calbox::modes {
namespace {

using geometry::Point2;

double distance(Point2 a, Point2 b) {
    return std::hypot(a.x - b.x, a.y - b.y);
}

// How the machine's frame lies in the photo's bed frame: mirrored or not, then turned and
// shifted.
struct FrameGuess {
    bool mirrored = false;
    solve::RigidPlacement placement;
    Point2 bed_of(Point2 machine) const {
        return placement.apply(mirrored ? Point2{machine.x, -machine.y} : machine);
    }
};

struct Matching {
    std::vector<long> candidate_of_hole;  // per target hole, -1 when none within reach
    int matched = 0, wrong_size = 0, at_omitted = 0;
    int score() const { return matched - 3 * wrong_size - 3 * at_omitted; }
};

long nearest_candidate(const std::vector<MarkCandidate>& candidates, Point2 at, double reach,
                       int* within = nullptr) {
    long best = -1;
    double best_d = reach;
    int count = 0;
    for (std::size_t i = 0; i < candidates.size(); ++i) {
        const double d = distance(candidates[i].bed_mm, at);
        if (d < reach) ++count;
        if (d < best_d) best_d = d, best = static_cast<long>(i);
    }
    if (within != nullptr) *within = count;
    return best;
}

Matching match_holes(const targets::PlanarTarget& target,
                     const std::vector<MarkCandidate>& candidates, const FrameGuess& frame,
                     double reach) {
    Matching m;
    for (const auto& hole : target.holes) {
        const long c = nearest_candidate(candidates, frame.bed_of(hole.centre_mm), reach);
        m.candidate_of_hole.push_back(c);
        if (c < 0) continue;
        ++m.matched;
        if (candidates[static_cast<std::size_t>(c)].large != hole.large) ++m.wrong_size;
    }
    if (nearest_candidate(candidates, frame.bed_of(target.node_mm(target.omitted)), reach) >= 0)
        ++m.at_omitted;
    return m;
}

// The frame from the two large holes: which seen one is which, and whether the photo's frame
// is mirrored, are tried all four ways.
FrameGuess frame_from_pair(const targets::PlanarTarget& target, Point2 first_seen,
                           Point2 second_seen, bool mirrored) {
    Point2 a{}, b{};
    for (const auto& hole : target.holes) {
        if (!hole.large) continue;
        if (hole.index.column == 1) a = hole.centre_mm;
        if (hole.index.column == 2) b = hole.centre_mm;
    }
    if (mirrored) a.y = -a.y, b.y = -b.y;
    FrameGuess g;
    g.mirrored = mirrored;
    g.placement = solve::best_rigid_placement({a, b}, {first_seen, second_seen});
    return g;
}

}  // namespace

std::vector<std::size_t> planar_design_nodes(const models::MachineFile& machine,
                                             std::size_t holes) {
    const auto full = targets::make_planar_target(machine);
    std::vector<Point2> candidates;
    std::vector<std::size_t> nodes;
    for (const auto& h : full.holes) {
        if (h.large) continue;  // made anyway, and not fitted
        candidates.push_back(h.centre_mm);
        nodes.push_back(geometry::grid_offset(h.index.column, h.index.row, full.columns));
    }
    if (holes < 8 || holes > candidates.size())
        throw PlanarError("design: " + std::to_string(holes) + " holes; choose 8 to " +
                          std::to_string(candidates.size()) + " of this machine's grid");
    std::vector<std::size_t> design;
    for (std::size_t i : models::detmax_design(candidates, holes, machine.planar->tool_length_mm))
        design.push_back(nodes[i]);
    std::sort(design.begin(), design.end());
    return design;
}

namespace {

// One photo's holes on its bed frame: odd ones set aside into `extra_mm`.
std::vector<MarkCandidate> holes_in_photo(const models::MachineFile& machine,
                                          const geometry::CameraModel& camera,
                                          const geometry::BedPlane& plane,
                                          const vision::GrayView& photo,
                                          const targets::PlanarTarget& target,
                                          const PlanarMeasureSettings& settings,
                                          std::vector<Point2>& extra_mm) {
    if (photo.width_px != camera.image_width || photo.height_px != camera.image_height)
        throw PlanarError("measure: the photo is " + std::to_string(photo.width_px) + "x" +
                          std::to_string(photo.height_px) + ", the camera was calibrated at " +
                          std::to_string(camera.image_width) + "x" +
                          std::to_string(camera.image_height));
    const vision::SpotImage seen = vision::find_spots(photo, settings.spots);
    const double small = 0.5 * target.hole_diameter_mm, large = 0.5 * target.large_diameter_mm;
    std::vector<MarkCandidate> candidates;
    for (const auto& m : marks_on_bed(camera, plane, seen, machine.planar->surface_height_mm)) {
        const bool is_small = m.radius_mm > 0.7 * small && m.radius_mm < 1.3 * small;
        const bool is_large = m.radius_mm > 0.8 * large && m.radius_mm < 1.2 * large;
        if (m.touches_border || m.elongation > settings.max_elongation || !(is_small || is_large)) {
            extra_mm.push_back(m.bed_mm);
            continue;
        }
        candidates.push_back({m.bed_mm, m.radius_mm, m.sigma_mm, is_large, false});
    }
    set_aside_odd_sizes(candidates, settings.max_radius_deviation, extra_mm);
    return candidates;
}

// The machine's frame in the first photo's bed frame, from its two large holes.
FrameGuess frame_from_fiducials(const targets::PlanarTarget& target,
                                const std::vector<MarkCandidate>& candidates, double reach) {
    const double pitch = target.pitch_mm;
    std::vector<std::pair<std::size_t, std::size_t>> pairs;
    for (std::size_t i = 0; i < candidates.size(); ++i)
        for (std::size_t j = i + 1; j < candidates.size(); ++j)
            if (candidates[i].large && candidates[j].large &&
                std::abs(distance(candidates[i].bed_mm, candidates[j].bed_mm) / pitch - 1) < 0.15)
                pairs.emplace_back(i, j);
    if (pairs.size() != 1)
        throw PlanarError(
            pairs.empty()
                ? "measure: the two large holes (the grid's fiducials, a pitch apart) are not in "
                  "the first photo: not this target, or they are damaged"
                : "measure: " + std::to_string(pairs.size()) +
                      " pairs of large holes a pitch apart: not this target (an ambiguous grid)");
    struct Reading {
        FrameGuess frame;
        Matching matching;
    };
    std::vector<Reading> readings;
    for (const bool mirrored : {false, true})
        for (const bool swapped : {false, true}) {
            const auto& [i, j] = pairs.front();
            const Point2 p = candidates[swapped ? j : i].bed_mm,
                         q = candidates[swapped ? i : j].bed_mm;
            const FrameGuess guess = frame_from_pair(target, p, q, mirrored);
            readings.push_back({guess, match_holes(target, candidates, guess, reach)});
        }
    std::sort(readings.begin(), readings.end(), [](const Reading& a, const Reading& b) {
        return a.matching.score() > b.matching.score();
    });
    // The best reading refined over the holes it matched (two holes a pitch apart leave the far
    // side of the sheet a few tenths of a degree out), then matched again.
    FrameGuess frame = readings[0].frame;
    {
        std::vector<Point2> from, to;
        for (std::size_t h = 0; h < target.holes.size(); ++h) {
            const long c = readings[0].matching.candidate_of_hole[h];
            if (c < 0) continue;
            const Point2 p = target.holes[h].centre_mm;
            from.push_back(frame.mirrored ? Point2{p.x, -p.y} : p);
            to.push_back(candidates[static_cast<std::size_t>(c)].bed_mm);
        }
        if (from.size() >= 3) frame.placement = solve::best_rigid_placement(from, to);
    }
    const Matching best = match_holes(target, candidates, frame, reach);
    // The right reading matches (nearly) every hole in the photo; a wrong one, those near the
    // fiducials at most.
    const int seen = static_cast<int>(candidates.size());
    if (best.wrong_size > 0 || best.at_omitted > 0 || 10 * best.matched < 9 * seen ||
        readings[1].matching.score() > best.score() - 3)
        throw PlanarError(
            "measure: the holes seen do not fit this target's " + std::to_string(target.columns) +
            " x " + std::to_string(target.rows) + " grid at " + number_text("%g", pitch) + " mm (" +
            std::to_string(best.matched) + " of the " + std::to_string(seen) +
            " holes seen where it puts them, " + std::to_string(best.wrong_size + best.at_omitted) +
            " of the wrong size or where none was drilled): not this target, or the "
            "wrong pitch in [planar]");
    return readings[0].frame;
}

// Every node's hole in one photo, through a frame good to a fraction of the reach: the candidate
// index per target hole (-1: none), refusing two holes where the grid has one.
std::vector<long> index_holes(const targets::PlanarTarget& target,
                              const std::vector<MarkCandidate>& candidates, FrameGuess& frame,
                              double reach) {
    // Refined over every hole matched: a frame from two holes, or from where the camera was
    // sent, leaves the far side of the photo a few tenths of a degree out.
    Matching m = match_holes(target, candidates, frame, reach);
    std::vector<Point2> from, to;
    for (std::size_t h = 0; h < target.holes.size(); ++h) {
        const long c = m.candidate_of_hole[h];
        if (c < 0) continue;
        const Point2 p = target.holes[h].centre_mm;
        from.push_back(frame.mirrored ? Point2{p.x, -p.y} : p);
        to.push_back(candidates[static_cast<std::size_t>(c)].bed_mm);
    }
    if (from.size() >= 3) frame.placement = solve::best_rigid_placement(from, to);
    m = match_holes(target, candidates, frame, reach);
    std::vector<bool> used(candidates.size(), false);
    for (std::size_t h = 0; h < target.holes.size(); ++h) {
        const auto& hole = target.holes[h];
        const long c = m.candidate_of_hole[h];
        int within = 0;
        nearest_candidate(candidates, frame.bed_of(hole.centre_mm), reach, &within);
        if (within > 1 || (c >= 0 && used[static_cast<std::size_t>(c)])) {
            const Point2 at = frame.bed_of(hole.centre_mm);
            throw PlanarError("measure: two holes where the grid has one, near hole (" +
                              std::to_string(hole.index.column) + ", " +
                              std::to_string(hole.index.row) + ") at bed X" +
                              number_text("%.1f", at.x) + " Y" + number_text("%.1f", at.y) +
                              ": a duplicate or ambiguous grid; nothing measured");
        }
        if (c >= 0) used[static_cast<std::size_t>(c)] = true;
    }
    return m.candidate_of_hole;
}

}  // namespace

PlanarMeasurement measure_planar(const models::MachineFile& machine,
                                 const geometry::CameraModel& camera,
                                 const geometry::BedPlane& plane, const vision::GrayView& photo,
                                 const PlanarMeasureSettings& settings) {
    return measure_planar_views(machine, camera, plane, {{photo, {0, 0}}}, settings);
}

PlanarMeasurement measure_planar_views(const models::MachineFile& machine,
                                       const geometry::CameraModel& camera,
                                       const geometry::BedPlane& plane,
                                       const std::vector<PlanarView>& views,
                                       const PlanarMeasureSettings& settings) {
    if (views.empty()) throw PlanarError("measure: no photo");
    const auto target = targets::make_planar_target(machine, settings.target);
    const double reach = settings.match_reach_pitch * target.pitch_mm;
    PlanarMeasurement out;
    out.machine_fingerprint = models::fingerprint(machine);
    out.target_fingerprint = target.fingerprint;
    out.columns = target.columns;
    out.rows = target.rows;
    out.pitch_mm = target.pitch_mm;
    std::vector<std::vector<MarkCandidate>> candidates;
    candidates.reserve(views.size());
    for (const auto& view : views)
        candidates.push_back(
            holes_in_photo(machine, camera, plane, view.photo, target, settings, out.extra_mm));
    if (candidates[0].size() < 8)
        throw PlanarError("measure: " + std::to_string(candidates[0].size()) +
                          " holes of the grid's size in the first photo, the target has " +
                          std::to_string(target.holes.size()) +
                          ": not this target, or the photo does not show it");
    const FrameGuess first = frame_from_fiducials(target, candidates[0], reach);
    out.mirrored = first.mirrored;
    // Each view indexed through where the camera was sent: the machine moved it by its offset
    // from the first view's, so a machine point m shows where the first view showed m - offset.
    // That is good to the machine's errors (a few millimetres), enough to say which hole is
    // which; where the holes are comes from the photos alone.
    std::vector<std::vector<long>> index;                       // per view, per target hole
    std::optional<std::pair<std::size_t, long>> backlash_seen;  // view, candidate
    for (std::size_t v = 0; v < views.size(); ++v) {
        FrameGuess frame = first;
        const Point2 shift{views[v].offset_mm.x - views[0].offset_mm.x,
                           views[v].offset_mm.y - views[0].offset_mm.y};
        const Point2 at_origin = first.bed_of({0, 0}), moved = first.bed_of(shift);
        frame.placement.translation_mm = {
            frame.placement.translation_mm.x - (moved.x - at_origin.x),
            frame.placement.translation_mm.y - (moved.y - at_origin.y)};
        index.push_back(index_holes(target, candidates[v], frame, reach));
        if (target.backlash_hole && !backlash_seen) {
            // Half a pitch diagonally from four grid holes: within the reach of none of theirs.
            const long c = nearest_candidate(candidates[v],
                                             frame.bed_of(target.backlash_hole->centre_mm), reach);
            if (c >= 0 &&
                std::find(index.back().begin(), index.back().end(), c) == index.back().end() &&
                !candidates[v][static_cast<std::size_t>(c)].large)
                backlash_seen = std::pair<std::size_t, long>{v, c};
        }
    }
    // Stitched through the holes the views share: each view's own rotation and shift (the first
    // view's fixed) and every hole's position, by least squares, so that a hole seen twice is
    // seen at one place. Started from the offsets the machine was sent to.
    const std::size_t n_views = views.size(), n_holes = target.holes.size();
    std::vector<double> angle(n_views, 0);
    std::vector<Point2> shift(n_views);
    for (std::size_t v = 0; v < n_views; ++v) {
        const Point2 a = first.bed_of({0, 0}),
                     b = first.bed_of({views[v].offset_mm.x - views[0].offset_mm.x,
                                       views[v].offset_mm.y - views[0].offset_mm.y});
        shift[v] = {b.x - a.x, b.y - a.y};
    }
    std::vector<int> seen_in(n_holes, 0);
    for (std::size_t v = 0; v < n_views; ++v)
        for (std::size_t h = 0; h < n_holes; ++h) seen_in[h] += index[v][h] >= 0 ? 1 : 0;
    for (std::size_t v = 1; v < n_views; ++v) {
        int shared = 0;
        for (std::size_t h = 0; h < n_holes; ++h)
            if (index[v][h] >= 0 && seen_in[h] > 1) ++shared;
        if (shared < 3)
            throw PlanarError("measure: photo " + std::to_string(v + 1) + " shares " +
                              std::to_string(shared) +
                              " holes with the others; overlapping photos need at least 3");
    }
    const auto place = [&](std::size_t v, Point2 b) {
        const double c = std::cos(angle[v]), sn = std::sin(angle[v]);
        return Point2{c * b.x - sn * b.y + shift[v].x, sn * b.x + c * b.y + shift[v].y};
    };
    std::vector<Point2> position(n_holes);
    const auto average = [&] {
        for (std::size_t h = 0; h < n_holes; ++h) {
            Point2 sum;
            int n = 0;
            for (std::size_t v = 0; v < n_views; ++v)
                if (const long c = index[v][h]; c >= 0) {
                    const Point2 p = place(v, candidates[v][static_cast<std::size_t>(c)].bed_mm);
                    sum.x += p.x, sum.y += p.y, ++n;
                }
            if (n > 0) position[h] = {sum.x / n, sum.y / n};
        }
    };
    average();
    if (n_views > 1) {
        // Gauss-Newton over every view's rotation and shift (the first view's fixed: it sets
        // the frame) and every shared hole's position: a hole seen in view v at b lies at
        // R(angle_v) b + shift_v. Holes seen once follow from their view afterwards.
        std::vector<long> unknown_of_hole(n_holes, -1);
        Eigen::Index unknowns = 3 * static_cast<Eigen::Index>(n_views - 1);
        for (std::size_t h = 0; h < n_holes; ++h)
            if (seen_in[h] > 1) unknown_of_hole[h] = unknowns, unknowns += 2;
        for (int iteration = 0; iteration < 6; ++iteration) {
            std::vector<Eigen::Triplet<double>> entries;
            std::vector<double> residual;
            for (std::size_t v = 0; v < n_views; ++v)
                for (std::size_t h = 0; h < n_holes; ++h) {
                    const long c = index[v][h];
                    if (c < 0 || unknown_of_hole[h] < 0) continue;
                    const Point2 b = candidates[v][static_cast<std::size_t>(c)].bed_mm;
                    const Point2 p = place(v, b);
                    const auto row = static_cast<Eigen::Index>(residual.size());
                    residual.push_back(position[h].x - p.x);
                    residual.push_back(position[h].y - p.y);
                    if (v > 0) {
                        const auto k = 3 * static_cast<Eigen::Index>(v - 1);
                        // d(place)/d(angle) = (-(p.y - shift.y), p.x - shift.x).
                        entries.emplace_back(row, k, -(p.y - shift[v].y));
                        entries.emplace_back(row + 1, k, p.x - shift[v].x);
                        entries.emplace_back(row, k + 1, 1.0);
                        entries.emplace_back(row + 1, k + 2, 1.0);
                    }
                    entries.emplace_back(row, unknown_of_hole[h], -1.0);
                    entries.emplace_back(row + 1, unknown_of_hole[h] + 1, -1.0);
                }
            Eigen::SparseMatrix<double> jacobian(static_cast<Eigen::Index>(residual.size()),
                                                 unknowns);
            jacobian.setFromTriplets(entries.begin(), entries.end());
            const Eigen::Map<const Eigen::VectorXd> r(residual.data(),
                                                      static_cast<Eigen::Index>(residual.size()));
            const Eigen::SparseMatrix<double> normal = jacobian.transpose() * jacobian;
            Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
            const Eigen::VectorXd step = solver.solve(jacobian.transpose() * r);
            if (solver.info() != Eigen::Success)
                throw PlanarError("measure: the photos' shared holes do not fix how they lie");
            double largest = 0;
            for (std::size_t v = 1; v < n_views; ++v) {
                const auto k = 3 * static_cast<Eigen::Index>(v - 1);
                angle[v] += step(k);
                shift[v].x += step(k + 1);
                shift[v].y += step(k + 2);
                largest = std::max({largest, std::abs(step(k + 1)), std::abs(step(k + 2))});
            }
            for (std::size_t h = 0; h < n_holes; ++h)
                if (unknown_of_hole[h] >= 0) {
                    position[h].x += step(unknown_of_hole[h]);
                    position[h].y += step(unknown_of_hole[h] + 1);
                }
            if (largest < 1e-9) break;
        }
        average();
    }
    std::size_t found = 0;
    for (std::size_t h = 0; h < n_holes; ++h) {
        const auto& hole = target.holes[h];
        if (seen_in[h] == 0) {
            out.missing.push_back(hole.index);
            continue;
        }
        ++found;
        double inverse_variance = 0;
        for (std::size_t v = 0; v < n_views; ++v)
            if (const long c = index[v][h]; c >= 0) {
                const double sigma = candidates[v][static_cast<std::size_t>(c)].sigma_mm;
                inverse_variance += 1 / std::max(sigma * sigma, 1e-18);
            }
        const Point2 p = position[h];
        out.holes.push_back({hole.index, hole.centre_mm, hole.large,
                             out.mirrored ? Point2{p.x, -p.y} : p,
                             1 / std::sqrt(inverse_variance)});
    }
    if (backlash_seen) {
        const auto& [v, c] = *backlash_seen;
        const auto& candidate = candidates[v][static_cast<std::size_t>(c)];
        const Point2 p = place(v, candidate.bed_mm);
        out.backlash_hole =
            PlanarHoleMeasurement{target.backlash_hole->index, target.backlash_hole->centre_mm,
                                  false, out.mirrored ? Point2{p.x, -p.y} : p, candidate.sigma_mm};
    }
    for (std::size_t v = 0; v < n_views; ++v) {
        std::vector<bool> used(candidates[v].size(), false);
        for (const long c : index[v])
            if (c >= 0) used[static_cast<std::size_t>(c)] = true;
        if (backlash_seen && backlash_seen->first == v)
            used[static_cast<std::size_t>(backlash_seen->second)] = true;
        for (std::size_t i = 0; i < used.size(); ++i)
            if (!used[i]) out.extra_mm.push_back(place(v, candidates[v][i].bed_mm));
    }
    if (found < (3 * n_holes + 3) / 4)
        throw PlanarError("measure: " + std::to_string(found) + " of the " +
                          std::to_string(n_holes) +
                          " holes found: part of the sheet is outside the photos, or whole rows "
                          "are missing");
    std::sort(out.holes.begin(), out.holes.end(), [](const auto& a, const auto& b) {
        return std::make_pair(a.index.row, a.index.column) <
               std::make_pair(b.index.row, b.index.column);
    });
    return out;
}

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
    // Before: what the holes show once only the machine's placement in the photo is taken out.
    const auto placement = solve::best_rigid_placement(seen, s.commanded_mm);
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
    if (measured.backlash_hole) {
        // Seen = R (c + e(c)) + t for a hole approached like the others; the rest is the slack,
        // less what the model leaves unexplained there: the mean residual of the cell's four
        // corner holes (the unexplained part changes slowly over a cell, the slack not at all).
        const auto& hole = *measured.backlash_hole;
        const double c = std::cos(s.fit.rotation_rad), sn = std::sin(s.fit.rotation_rad);
        const double dx = hole.measured_mm.x - s.fit.translation_mm.x,
                     dy = hole.measured_mm.y - s.fit.translation_mm.y;
        const Point2 e =
            models::planar_error_mm(s.fit.parameters, hole.commanded_mm, s.tool_length_mm);
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
        s.backlash_mm = Point2{c * dx + sn * dy - hole.commanded_mm.x - e.x - local.x,
                               -sn * dx + c * dy - hole.commanded_mm.y - e.y - local.y};
    }
    s.rigid_part = models::rigid_part_of(s.fit.parameters, s.tool_length_mm, s.min_x_mm, s.min_y_mm,
                                         s.max_x_mm, s.max_y_mm);
    // Bounds on what will be sent: the correction over the whole valid area, corners included.
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
    return s;
}

Point2 planar_command_for(const PlanarSolution& s, Point2 intended_mm) {
    return models::planar_command_for(s.fit.parameters, intended_mm, s.tool_length_mm,
                                      s.rigid_part);
}

bool planar_covers(const PlanarSolution& s, Point2 p) {
    // Half a pitch's grace is not taken: outside the measured holes the model extrapolates.
    return p.x >= s.min_x_mm - 1e-9 && p.x <= s.max_x_mm + 1e-9 && p.y >= s.min_y_mm - 1e-9 &&
           p.y <= s.max_y_mm + 1e-9;
}

FirmwareSettings planar_firmware_settings(const models::MachineFile& machine,
                                          const PlanarSolution& s) {
    // Scale and skew settings can carry the field's linear part over the area only: the best
    // affine fit of e over the measured holes, its rotation left to the work's heading.
    // e ~ (a x + b y + tx, c x + d y + ty); turned by -c it is (a x + (b + c) y, d y): x scale a,
    // y scale d, and x moving (b + c) per mm of y.
    Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> right = Eigen::Matrix<double, 6, 1>::Zero();
    std::vector<Point2> field;
    for (std::size_t i = 0; i < s.commanded_mm.size(); ++i) {
        const Point2 c = s.commanded_mm[i];
        const Point2 e = models::planar_error_mm(s.fit.parameters, c, s.tool_length_mm);
        field.push_back({e.x + s.fit.residuals_mm[i].x, e.y + s.fit.residuals_mm[i].y});
        Eigen::Matrix<double, 6, 1> rx, ry;
        rx << c.x, c.y, 0, 0, 1, 0;
        ry << 0, 0, c.x, c.y, 0, 1;
        normal += rx * rx.transpose() + ry * ry.transpose();
        right += rx * field.back().x + ry * field.back().y;
    }
    const Eigen::Matrix<double, 6, 1> affine = normal.ldlt().solve(right);
    const double sx = affine(0), sy = affine(3), skew = affine(1) + affine(2);
    FirmwareSettings f;
    f.scale_x = sx, f.scale_y = sy, f.skew = skew;
    // What they leave: the field less its linear part, the placement out.
    std::vector<Point2> left, commanded_plus;
    for (std::size_t i = 0; i < field.size(); ++i) {
        const Point2 c = s.commanded_mm[i];
        left.push_back({field[i].x - sx * c.x - skew * c.y, field[i].y - sy * c.y});
        commanded_plus.push_back({c.x + left.back().x, c.y + left.back().y});
    }
    std::vector<Point2> placed_left;
    const auto placement = solve::best_rigid_placement(commanded_plus, s.commanded_mm);
    for (std::size_t i = 0; i < left.size(); ++i) {
        const Point2 p = placement.apply(commanded_plus[i]);
        placed_left.push_back({p.x - s.commanded_mm[i].x, p.y - s.commanded_mm[i].y});
    }
    f.mean_left_mm = models::norm_statistics(placed_left).mean_mm;
    f.mean_before_mm = s.before.mean_mm;
    // An axis that travels (1 + s) too far needs 1 / (1 + s) of its steps per mm.
    const double fx = 1 / (1 + sx), fy = 1 / (1 + sy);
    const auto& planar = *machine.planar;
    auto& out = f.lines;
    out.emplace_back("; calbox planar, the best linear fit over the holes: x travels " +
                     number_text("%+.4f", 100 * sx) + " %, y " + number_text("%+.4f", 100 * sy) +
                     " %, the axes are " + number_text("%+.4f", skew * 1000) +
                     " mrad out of square (x moves " + number_text("%+.6f", skew) +
                     " mm per mm of y)");
    if (s.backlash_mm)
        out.emplace_back("; backlash " + number_text("%.3f", s.backlash_mm->x) + " mm in x, " +
                         number_text("%.3f", s.backlash_mm->y) +
                         " mm in y (the hole drilled from the other side): jobs that approach "
                         "their features from one side do not see it");
    out.emplace_back("; these settings leave " + number_text("%.3f", f.mean_left_mm) +
                     " mm mean error norm of " + number_text("%.3f", f.mean_before_mm) +
                     " (straightness, yaw and what the model does not hold); the compensated "
                     "G-code corrects all of the model");
    const bool steps = planar.steps_per_mm_x && planar.steps_per_mm_y;
    const std::string factors = "multiply X steps/mm by " + number_text("%.6f", fx) + " and Y by " +
                                number_text("%.6f", fy);
    if (machine.firmware == "marlin") {
        out.emplace_back(steps ? "M92 X" + number_text("%.4f", *planar.steps_per_mm_x * fx) + " Y" +
                                     number_text("%.4f", *planar.steps_per_mm_y * fy)
                               : "; M92: " + factors);
        // Marlin's skew correction moves x by -y * I: I is the lean measured.
        out.emplace_back("M852 I" + number_text("%.6f", skew));
        if (s.backlash_mm)
            out.emplace_back("M425 X" + number_text("%.3f", std::max(0.0, s.backlash_mm->x)) +
                             " Y" + number_text("%.3f", std::max(0.0, s.backlash_mm->y)));
        out.emplace_back("M500");
    } else if (machine.firmware == "grbl") {
        if (steps) {
            out.emplace_back("$100=" + number_text("%.4f", *planar.steps_per_mm_x * fx));
            out.emplace_back("$101=" + number_text("%.4f", *planar.steps_per_mm_y * fy));
        } else {
            out.emplace_back("; $100, $101: " + factors);
        }
        out.emplace_back("; grbl has no skew setting: use the compensated G-code for squareness");
    } else if (machine.firmware == "klipper") {
        out.emplace_back("; [stepper_x] rotation_distance: multiply by " +
                         number_text("%.6f", 1 + sx) + ", [stepper_y] by " +
                         number_text("%.6f", 1 + sy));
        // The diagonals and side of a 100 mm square as this machine makes it, after the scales
        // are set: Klipper's skew calibration takes them as measured.
        const double side = 100;
        const Point2 a{0, 0}, b{side, 0}, c{side + skew * side, side}, d{skew * side, side};
        out.emplace_back("SET_SKEW XY=" + number_text("%.4f", distance(a, c)) + "," +
                         number_text("%.4f", distance(b, d)) + "," +
                         number_text("%.4f", distance(a, d)));
        out.emplace_back("SKEW_PROFILE SAVE=calbox");
        out.emplace_back("SAVE_CONFIG");
    } else if (machine.firmware == "linuxcnc") {
        out.emplace_back(
            "; [JOINT_0] COMP_FILE (COMP_FILE_TYPE = 0: nominal actual), and the same "
            "for [JOINT_1] with y:");
        for (const double x : {s.min_x_mm, 0.5 * (s.min_x_mm + s.max_x_mm), s.max_x_mm})
            out.emplace_back("; " + number_text("%.3f", x) + " " +
                             number_text("%.4f", x * (1 + sx)));
        if (s.backlash_mm) {
            out.emplace_back("; [JOINT_0] BACKLASH = " +
                             number_text("%.3f", std::max(0.0, s.backlash_mm->x)));
            out.emplace_back("; [JOINT_1] BACKLASH = " +
                             number_text("%.3f", std::max(0.0, s.backlash_mm->y)));
        }
        out.emplace_back(
            "; linuxcnc has no skew setting: use the compensated G-code for squareness");
    } else {
        out.emplace_back("; " + machine.firmware + ": " + factors);
    }
    return f;
}

// ---------------------------------------------------------------------------------------------
// Files

namespace {

using nlohmann::json;

constexpr const char* kMeasurementsSchema = "calbox.planar-measurements/1";
constexpr const char* kResultSchema = "calbox.planar-result/1";

json statistics_json(const models::NormStatistics& s) {
    return {{"max_mm", s.max_mm}, {"q3_mm", s.q3_mm},   {"median_mm", s.median_mm},
            {"q1_mm", s.q1_mm},   {"min_mm", s.min_mm}, {"mean_mm", s.mean_mm},
            {"std_mm", s.std_mm}, {"points", s.points}};
}
models::NormStatistics statistics_from(const json& j) {
    models::NormStatistics s;
    s.max_mm = j.at("max_mm").get<double>();
    s.q3_mm = j.at("q3_mm").get<double>();
    s.median_mm = j.at("median_mm").get<double>();
    s.q1_mm = j.at("q1_mm").get<double>();
    s.min_mm = j.at("min_mm").get<double>();
    s.mean_mm = j.at("mean_mm").get<double>();
    s.std_mm = j.at("std_mm").get<double>();
    s.points = j.at("points").get<std::size_t>();
    return s;
}

}  // namespace

std::string planar_measurements_to_json(const PlanarMeasurement& m) {
    json holes = json::array(), missing = json::array(), extra = json::array();
    for (const auto& h : m.holes)
        holes.push_back({{"column", h.index.column},
                         {"row", h.index.row},
                         {"large", h.large},
                         {"commanded_mm", point_json(h.commanded_mm)},
                         {"measured_mm", point_json(h.measured_mm)},
                         {"sigma_mm", h.sigma_mm}});
    for (const auto& i : m.missing) missing.push_back({i.column, i.row});
    for (const auto& p : m.extra_mm) extra.push_back(point_json(p));
    json backlash = nullptr;
    if (m.backlash_hole)
        backlash = {{"column", m.backlash_hole->index.column},
                    {"row", m.backlash_hole->index.row},
                    {"commanded_mm", point_json(m.backlash_hole->commanded_mm)},
                    {"measured_mm", point_json(m.backlash_hole->measured_mm)},
                    {"sigma_mm", m.backlash_hole->sigma_mm}};
    const json j{{"schema", kMeasurementsSchema},
                 {"machine_fingerprint", m.machine_fingerprint},
                 {"target_fingerprint", m.target_fingerprint},
                 {"photos", m.photos},
                 {"columns", m.columns},
                 {"rows", m.rows},
                 {"pitch_mm", m.pitch_mm},
                 {"mirrored", m.mirrored},
                 {"holes", holes},
                 {"backlash_hole", backlash},
                 {"missing", missing},
                 {"extra_mm", extra}};
    return j.dump(1) + "\n";
}

PlanarMeasurement planar_measurements_from_json(const std::string& text,
                                                const std::string& source) {
    const json j = parse_record(text, source, kMeasurementsSchema, "planar measurements");
    try {
        PlanarMeasurement m;
        m.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        m.target_fingerprint = j.at("target_fingerprint").get<std::string>();
        m.photos = j.at("photos").get<std::vector<std::string>>();
        m.columns = j.at("columns").get<int>();
        m.rows = j.at("rows").get<int>();
        m.pitch_mm = j.at("pitch_mm").get<double>();
        m.mirrored = j.at("mirrored").get<bool>();
        if (m.columns < 7 || m.rows < 7 || !(m.pitch_mm > 0))
            throw RecordError(source + ": the grid must be at least 7 x 7 at a positive pitch");
        for (const auto& h : j.at("holes")) {
            PlanarHoleMeasurement p;
            p.index = {h.at("column").get<int>(), h.at("row").get<int>()};
            if (p.index.column < 0 || p.index.row < 0 || p.index.column >= m.columns ||
                p.index.row >= m.rows)
                throw RecordError(source + ": a hole lies outside the " +
                                  std::to_string(m.columns) + " x " + std::to_string(m.rows) +
                                  " grid");
            p.large = h.at("large").get<bool>();
            p.commanded_mm = point_from(h.at("commanded_mm"));
            p.measured_mm = point_from(h.at("measured_mm"));
            p.sigma_mm = h.at("sigma_mm").get<double>();
            m.holes.push_back(p);
        }
        if (const auto& b = j.at("backlash_hole"); !b.is_null()) {
            PlanarHoleMeasurement h;
            h.index = {b.at("column").get<int>(), b.at("row").get<int>()};
            h.commanded_mm = point_from(b.at("commanded_mm"));
            h.measured_mm = point_from(b.at("measured_mm"));
            h.sigma_mm = b.at("sigma_mm").get<double>();
            m.backlash_hole = h;
        }
        for (const auto& i : j.at("missing"))
            m.missing.push_back({i.at(0).get<int>(), i.at(1).get<int>()});
        for (const auto& p : j.at("extra_mm")) m.extra_mm.push_back(point_from(p));
        return m;
    } catch (const json::exception& e) {
        throw RecordError(source + ": " + e.what());
    }
}

std::string planar_result_to_json(const PlanarSolution& s, const FirmwareSettings& firmware) {
    const auto& names = models::planar_parameters();
    json parameters = json::array();
    for (std::size_t j = 0; j < names.size(); ++j) {
        json p{{"name", names[j].name},
               {"unit", names[j].unit},
               {"seed_symbol", names[j].seed_symbol},
               {"value", s.fit.parameters[j]},
               {"uncertainty", s.fit.uncertainty[j]},
               {"fitted", s.fit.fitted[j]}};
        for (const auto& h : s.fit.held)
            if (h.parameter == static_cast<int>(j)) p["absorbed_by"] = h.absorbed_by;
        parameters.push_back(p);
    }
    json holes = json::array();
    for (std::size_t i = 0; i < s.commanded_mm.size(); ++i)
        holes.push_back({{"commanded_mm", point_json(s.commanded_mm[i])},
                         {"error_mm", point_json(s.error_mm[i])},
                         {"residual_mm", point_json(s.fit.residuals_mm[i])}});
    const json j{{"schema", kResultSchema},
                 {"machine_fingerprint", s.machine_fingerprint},
                 {"tool_length_mm", s.tool_length_mm},
                 {"parameters", parameters},
                 {"placement",
                  {{"rotation_rad", s.fit.rotation_rad},
                   {"translation_mm", point_json(s.fit.translation_mm)}}},
                 {"rigid_part_left_out",
                  {{"rotation_rad", s.rigid_part.rotation_rad},
                   {"offset_mm", point_json(s.rigid_part.offset_mm)}}},
                 {"rank", s.fit.rank},
                 {"condition", s.fit.condition},
                 {"residual_rms_mm", s.fit.residual_rms_mm},
                 {"unit_variance_ratio", s.fit.unit_variance_ratio},
                 {"measurement_sigma_mm", s.measurement_sigma_mm},
                 {"before", statistics_json(s.before)},
                 {"after", statistics_json(s.after)},
                 {"valid_area_mm", {s.min_x_mm, s.min_y_mm, s.max_x_mm, s.max_y_mm}},
                 {"backlash_mm", s.backlash_mm ? point_json(*s.backlash_mm) : json(nullptr)},
                 {"firmware",
                  {{"lines", firmware.lines},
                   {"mean_left_mm", firmware.mean_left_mm},
                   {"mean_before_mm", firmware.mean_before_mm}}},
                 {"holes", holes}};
    return j.dump(1) + "\n";
}

PlanarSolution planar_result_from_json(const std::string& text, const std::string& source) {
    const json j = parse_record(text, source, kResultSchema, "planar result");
    try {
        PlanarSolution s;
        s.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        s.tool_length_mm = j.at("tool_length_mm").get<double>();
        const auto& names = models::planar_parameters();
        const json& parameters = j.at("parameters");
        if (!parameters.is_array() || parameters.size() != names.size())
            throw RecordError(source + ": parameters must list the model's " +
                              std::to_string(names.size()));
        for (std::size_t k = 0; k < names.size(); ++k) {
            const json& p = parameters[k];
            if (p.at("name").get<std::string>() != names[k].name)
                throw RecordError(source + ": parameter " + std::to_string(k) + " must be " +
                                  names[k].name);
            s.fit.parameters[k] = p.at("value").get<double>();
            s.fit.uncertainty[k] = p.at("uncertainty").get<double>();
            s.fit.fitted[k] = p.at("fitted").get<bool>();
            if (!std::isfinite(s.fit.parameters[k]))
                throw RecordError(source + ": parameter " + names[k].name + " is not finite");
        }
        s.fit.rotation_rad = j.at("placement").at("rotation_rad").get<double>();
        s.fit.translation_mm = point_from(j.at("placement").at("translation_mm"));
        s.rigid_part.rotation_rad = j.at("rigid_part_left_out").at("rotation_rad").get<double>();
        s.rigid_part.offset_mm = point_from(j.at("rigid_part_left_out").at("offset_mm"));
        s.fit.rank = j.at("rank").get<int>();
        s.fit.condition = j.at("condition").get<double>();
        s.fit.residual_rms_mm = j.at("residual_rms_mm").get<double>();
        s.fit.unit_variance_ratio = j.at("unit_variance_ratio").get<double>();
        s.measurement_sigma_mm = j.at("measurement_sigma_mm").get<double>();
        s.before = statistics_from(j.at("before"));
        s.after = statistics_from(j.at("after"));
        const auto area = j.at("valid_area_mm").get<std::vector<double>>();
        if (area.size() != 4 || !(area[2] > area[0] && area[3] > area[1]))
            throw RecordError(source + ": valid_area_mm is [min x, min y, max x, max y]");
        s.min_x_mm = area[0], s.min_y_mm = area[1], s.max_x_mm = area[2], s.max_y_mm = area[3];
        if (const auto& b = j.at("backlash_mm"); !b.is_null()) s.backlash_mm = point_from(b);
        for (const auto& h : j.at("holes")) {
            s.commanded_mm.push_back(point_from(h.at("commanded_mm")));
            s.error_mm.push_back(point_from(h.at("error_mm")));
            s.fit.residuals_mm.push_back(point_from(h.at("residual_mm")));
        }
        return s;
    } catch (const json::exception& e) {
        throw RecordError(source + ": " + e.what());
    }
}

}  // namespace calbox::modes
