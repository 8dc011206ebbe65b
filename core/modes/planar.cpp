// The planar mode's measure: the drilled (or printed) grid's holes found in the photos, indexed
// by the target's two large holes, and placed on the machine's frame.
#include "core/modes/planar.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include "core/geometry/placement.hpp"
#include "core/modes/json_file.hpp"
#include "core/modes/mark_grid.hpp"
#include "core/number_text.hpp"
#include "core/solve/view_stitching.hpp"

namespace calbox::modes {
namespace {

using geometry::Point2;

using geometry::distance;

// How the machine's frame lies in the photo's bed frame: mirrored or not, then turned and
// shifted.
struct FrameGuess {
    bool mirrored = false;
    geometry::RigidPlacement placement;
    Point2 bed_of(Point2 machine) const {
        return placement.apply(mirrored ? Point2{machine.x, -machine.y} : machine);
    }
};

struct HoleMatching {
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

HoleMatching match_holes(const targets::PlanarTarget& target,
                         const std::vector<MarkCandidate>& candidates, const FrameGuess& frame,
                         double reach) {
    HoleMatching m;
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
    g.placement = geometry::best_rigid_placement({a, b}, {first_seen, second_seen});
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
    if (const auto size = geometry::photo_size_mismatch(camera, photo.width_px, photo.height_px);
        !size.empty())
        throw PlanarError("measure: the photo is " + size);
    vision::SpotSettings spots = settings.spots;
    spots.polarity =
        machine.planar->holes == "light" ? vision::MarkPolarity::light : vision::MarkPolarity::dark;
    spots.mark_diameter_px =
        target.large_diameter_mm *
        pixels_per_mm_at_centre(camera, plane, machine.planar->surface_height_mm);
    // The work area lies within its diagonal of the plane's board, which lay on the bed.
    spots.search_outline_px = work_outline_px(
        camera, plane, machine.planar->surface_height_mm,
        std::hypot(machine.bed_size_x_mm, machine.bed_size_y_mm) + kOutlineMarginMm);
    const vision::SpotImage seen = vision::find_spots(photo, spots);
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
// The two large holes a pitch apart (the grid's fiducials), as indices into `candidates`;
// throws PlanarError where there is no such pair or more than one.
std::pair<std::size_t, std::size_t> fiducial_pair(const targets::PlanarTarget& target,
                                                  const std::vector<MarkCandidate>& candidates) {
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
    return pairs.front();
}

// `guess` refined over the holes `matching` matched to it (two holes a pitch apart leave the far
// side of the sheet a few tenths of a degree out); as it was with fewer than three.
FrameGuess refined_frame(const targets::PlanarTarget& target,
                         const std::vector<MarkCandidate>& candidates, FrameGuess guess,
                         const HoleMatching& matching) {
    std::vector<Point2> from, to;
    for (std::size_t h = 0; h < target.holes.size(); ++h) {
        const long c = matching.candidate_of_hole[h];
        if (c < 0) continue;
        const Point2 p = target.holes[h].centre_mm;
        from.push_back(guess.mirrored ? Point2{p.x, -p.y} : p);
        to.push_back(candidates[static_cast<std::size_t>(c)].bed_mm);
    }
    if (from.size() >= 3) guess.placement = geometry::best_rigid_placement(from, to);
    return guess;
}

FrameGuess frame_from_fiducials(const targets::PlanarTarget& target,
                                const std::vector<MarkCandidate>& candidates, double reach) {
    const double pitch = target.pitch_mm;
    const auto [i, j] = fiducial_pair(target, candidates);
    struct Reading {
        FrameGuess frame;
        HoleMatching matching;
    };
    std::vector<Reading> readings;
    for (const bool mirrored : {false, true})
        for (const bool swapped : {false, true}) {
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
    const FrameGuess frame =
        refined_frame(target, candidates, readings[0].frame, readings[0].matching);
    const HoleMatching best = match_holes(target, candidates, frame, reach);
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
    HoleMatching m = match_holes(target, candidates, frame, reach);
    frame = refined_frame(target, candidates, frame, m);
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

namespace {

// The holes each view shows, by the target's holes: -1 where a view shows none.
using ViewIndex = std::vector<std::vector<long>>;
// The view and candidate where the backlash hole was seen.
using SeenAt = std::optional<std::pair<std::size_t, long>>;

// Each view indexed through where the camera was sent: the machine moved it by its offset
// from the first view's, so a machine point m shows where the first view showed m - offset.
// That is good to the machine's errors (a few millimetres), enough to say which hole is
// which; where the holes are comes from the photos alone.
ViewIndex index_views(const targets::PlanarTarget& target, const std::vector<PlanarView>& views,
                      const std::vector<std::vector<MarkCandidate>>& candidates,
                      const FrameGuess& first, double reach, SeenAt& backlash_seen) {
    ViewIndex index;
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
    return index;
}

// How many views show each of the target's holes.
std::vector<int> times_seen(const ViewIndex& index, std::size_t n_holes) {
    std::vector<int> seen_in(n_holes, 0);
    for (const auto& view : index)
        for (std::size_t h = 0; h < n_holes; ++h) seen_in[h] += view[h] >= 0 ? 1 : 0;
    return seen_in;
}

// Stitched through the holes the views share: each view's own rotation and shift (the first
// view's fixed) and every hole's position, by least squares, so that a hole seen twice is
// seen at one place. Started from the offsets the machine was sent to.
solve::ViewStitch stitch_the_views(const std::vector<PlanarView>& views, const FrameGuess& first,
                                   const ViewIndex& index,
                                   const std::vector<std::vector<MarkCandidate>>& candidates) {
    const std::size_t n_views = views.size(), n_holes = index.empty() ? 0 : index[0].size();
    std::vector<Point2> start_shift(n_views);
    for (std::size_t v = 0; v < n_views; ++v) {
        const Point2 a = first.bed_of({0, 0}),
                     b = first.bed_of({views[v].offset_mm.x - views[0].offset_mm.x,
                                       views[v].offset_mm.y - views[0].offset_mm.y});
        start_shift[v] = {b.x - a.x, b.y - a.y};
    }
    const std::vector<int> seen_in = times_seen(index, n_holes);
    for (std::size_t v = 1; v < n_views; ++v) {
        int shared = 0;
        for (std::size_t h = 0; h < n_holes; ++h)
            if (index[v][h] >= 0 && seen_in[h] > 1) ++shared;
        if (shared < 3)
            throw PlanarError("measure: photo " + std::to_string(v + 1) + " shares " +
                              std::to_string(shared) +
                              " holes with the others; overlapping photos need at least 3");
    }
    std::vector<std::vector<std::optional<Point2>>> seen(n_views);
    for (std::size_t v = 0; v < n_views; ++v) {
        seen[v].resize(n_holes);
        for (std::size_t h = 0; h < n_holes; ++h)
            if (const long c = index[v][h]; c >= 0)
                seen[v][h] = candidates[v][static_cast<std::size_t>(c)].bed_mm;
    }
    try {
        return solve::stitch_views(seen, std::move(start_shift));
    } catch (const solve::StitchError&) {
        throw PlanarError("measure: the photos' shared holes do not fix how they lie");
    }
}

// Each hole's place where the views saw it, its sigma from theirs; the holes none saw, missing.
// Returns how many were found.
std::size_t place_holes(PlanarMeasurement& out, const targets::PlanarTarget& target,
                        const ViewIndex& index,
                        const std::vector<std::vector<MarkCandidate>>& candidates,
                        const std::vector<int>& seen_in, const solve::ViewStitch& stitch) {
    const std::size_t n_views = index.size(), n_holes = target.holes.size();
    const auto& position = stitch.position_mm;
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
    return found;
}

// The backlash hole's place, and every candidate no hole took, as extras on the bed.
void place_the_rest(PlanarMeasurement& out, const targets::PlanarTarget& target,
                    const ViewIndex& index,
                    const std::vector<std::vector<MarkCandidate>>& candidates,
                    const SeenAt& backlash_seen, const solve::ViewStitch& stitch) {
    const std::size_t n_views = index.size();
    const auto place = [&stitch](std::size_t v, Point2 b) { return stitch.place(v, b); };
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
}

}  // namespace

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
    SeenAt backlash_seen;
    const ViewIndex index = index_views(target, views, candidates, first, reach, backlash_seen);
    const solve::ViewStitch stitch = stitch_the_views(views, first, index, candidates);
    const std::size_t n_holes = target.holes.size();
    const std::size_t found =
        place_holes(out, target, index, candidates, times_seen(index, n_holes), stitch);
    place_the_rest(out, target, index, candidates, backlash_seen, stitch);
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

}  // namespace calbox::modes
