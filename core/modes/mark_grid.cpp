#include "core/modes/mark_grid.hpp"

#include <algorithm>
#include <cmath>
#include <deque>

#include "core/median.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {
namespace {

using geometry::Point2;

// Candidates by position, in cells of one pitch.
class Neighbourhood {
  public:
    Neighbourhood(std::vector<MarkCandidate>& candidates, double cell_mm)
        : candidates_(candidates), cell_(cell_mm) {
        for (std::size_t i = 0; i < candidates.size(); ++i)
            cells_[key(candidates[i].bed_mm)].push_back(i);
    }
    // The nearest free candidate within `reach_mm` of `at`, or -1.
    long nearest(Point2 at, double reach_mm) const {
        long best = -1;
        double best_d = reach_mm;
        const auto [kx, ky] = key(at);
        for (long dy = -1; dy <= 1; ++dy)
            for (long dx = -1; dx <= 1; ++dx) {
                const auto it = cells_.find({kx + dx, ky + dy});
                if (it == cells_.end()) continue;
                for (std::size_t i : it->second) {
                    if (candidates_[i].taken) continue;
                    const double d =
                        std::hypot(candidates_[i].bed_mm.x - at.x, candidates_[i].bed_mm.y - at.y);
                    if (d < best_d) best_d = d, best = static_cast<long>(i);
                }
            }
        return best;
    }

  private:
    std::pair<long, long> key(Point2 p) const {
        return {static_cast<long>(std::floor(p.x / cell_)),
                static_cast<long>(std::floor(p.y / cell_))};
    }
    std::vector<MarkCandidate>& candidates_;
    double cell_;
    std::map<std::pair<long, long>, std::vector<std::size_t>> cells_;
};

}  // namespace

namespace {

// Each pixel with the one to its right and the one below it, on the bed: the bed area a pixel
// covers there comes out in both directions (a tilted view foreshortens one).
std::vector<geometry::Point3> with_neighbours_on_bed(const geometry::CameraModel& camera,
                                                     const geometry::BedPlane& plane,
                                                     const std::vector<Point2>& at_px,
                                                     double height_mm) {
    std::vector<Point2> pixels;
    pixels.reserve(3 * at_px.size());
    for (const auto& p : at_px) {
        pixels.push_back(p);
        pixels.push_back({p.x + 1, p.y});
        pixels.push_back({p.x, p.y + 1});
    }
    return geometry::pixels_to_bed(camera, plane, pixels, height_mm);
}

// The bed area of the pixel whose three points start at `on_bed[3 * i]`, mm^2.
double mm2_per_pixel(const std::vector<geometry::Point3>& on_bed, std::size_t i) {
    const auto& c = on_bed[3 * i];
    const Point2 du{on_bed[3 * i + 1].x - c.x, on_bed[3 * i + 1].y - c.y};
    const Point2 dv{on_bed[3 * i + 2].x - c.x, on_bed[3 * i + 2].y - c.y};
    return std::abs(du.x * dv.y - du.y * dv.x);
}

}  // namespace

std::vector<SeenMark> marks_on_bed(const geometry::CameraModel& camera,
                                   const geometry::BedPlane& plane, const vision::SpotImage& seen,
                                   double height_mm) {
    std::vector<Point2> centres;
    centres.reserve(seen.spots.size());
    for (const auto& s : seen.spots) centres.push_back(s.centre_px);
    const auto on_bed = with_neighbours_on_bed(camera, plane, centres, height_mm);
    std::vector<SeenMark> marks;
    for (std::size_t i = 0; i < seen.spots.size(); ++i) {
        const auto& s = seen.spots[i];
        const double mm2_per_px = mm2_per_pixel(on_bed, i);
        marks.push_back({{on_bed[3 * i].x, on_bed[3 * i].y},
                         std::sqrt(s.area_px * mm2_per_px / 3.14159265358979),
                         s.sigma_px * std::sqrt(mm2_per_px),
                         s.elongation,
                         s.touches_border});
    }
    return marks;
}

double pixels_per_mm_at_centre(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               double height_mm) {
    const auto on_bed =
        with_neighbours_on_bed(camera, plane, {{camera.cx(), camera.cy()}}, height_mm);
    return 1 / std::sqrt(mm2_per_pixel(on_bed, 0));
}

std::vector<Point2> work_outline_px(const geometry::CameraModel& camera,
                                    const geometry::BedPlane& plane, double height_mm,
                                    double reach_mm) {
    constexpr int kSides = 72;
    std::vector<geometry::Point3> circle;
    for (int k = 0; k < kSides; ++k) {
        const double a = 2 * 3.14159265358979 * k / kSides;
        circle.push_back({reach_mm * std::cos(a), reach_mm * std::sin(a), height_mm});
    }
    const auto pixels = geometry::project_points(camera, plane.bed_to_camera, circle);
    // A point behind the camera projects too, mirrored: each must map back to where it was.
    try {
        const auto back = geometry::pixels_to_bed(camera, plane, pixels, height_mm);
        for (std::size_t k = 0; k < circle.size(); ++k)
            if (std::hypot(back[k].x - circle[k].x, back[k].y - circle[k].y) > 0.01 * reach_mm)
                return {};
    } catch (const geometry::CalibrationError&) {
        return {};
    }
    return pixels;
}

void set_aside_odd_sizes(std::vector<MarkCandidate>& candidates, double max_deviation,
                         std::vector<Point2>& extra_mm) {
    for (const bool kind : {false, true}) {
        std::vector<double> radii;
        for (const auto& c : candidates)
            if (c.large == kind) radii.push_back(c.radius_mm);
        if (radii.empty()) continue;
        const double typical = median_of(radii);
        // The kind's own spread, as a standard deviation from the median absolute deviation:
        // small marks seen by few pixels measure a few percent apart even when made alike.
        std::vector<double> deviations;
        deviations.reserve(radii.size());
        for (const double r : radii) deviations.push_back(std::abs(r / typical - 1));
        const double allowed =
            std::max(max_deviation, kSizeSpreadsAllowed * 1.4826 * median_of(deviations));
        for (auto& c : candidates)
            if (c.large == kind && std::abs(c.radius_mm / typical - 1) > allowed) c.taken = true;
    }
    for (auto it = candidates.begin(); it != candidates.end();) {
        if (it->taken) {
            extra_mm.push_back(it->bed_mm);
            it = candidates.erase(it);
        } else {
            ++it;
        }
    }
}

// Indexes the candidates on a square lattice of pitch `pitch` by growing it from the middle
// mark: each neighbour is looked for where the node and the one behind it predict it, so the
// lattice follows a distortion that bends it slowly; a single gap is bridged by a predicted node.
Lattice grow_lattice(std::vector<MarkCandidate>& candidates, double pitch, double reach) {
    Neighbourhood near(candidates, pitch);
    Point2 mean;
    for (const auto& c : candidates) mean.x += c.bed_mm.x, mean.y += c.bed_mm.y;
    mean.x /= static_cast<double>(candidates.size()),
        mean.y /= static_cast<double>(candidates.size());
    const long seed = near.nearest(mean, 1e300);
    candidates[static_cast<std::size_t>(seed)].taken = true;
    const Point2 origin = candidates[static_cast<std::size_t>(seed)].bed_mm;
    // The lattice's axes from the middle mark's nearest neighbour, turned by the quarter turn
    // that brings it closest to the bed's +x (the neighbour there may have misfired), so that
    // the symmetry found says how the grid lies on the bed.
    const long first = near.nearest(origin, 1.4 * pitch);
    if (first < 0)
        throw LatticeError("measure: no mark lies a pitch from another: not a grid of " +
                           number_text("%.3f", pitch) + " mm pitch");
    Point2 e1{candidates[static_cast<std::size_t>(first)].bed_mm.x - origin.x,
              candidates[static_cast<std::size_t>(first)].bed_mm.y - origin.y};
    if (std::hypot(e1.x, e1.y) < 0.7 * pitch)
        throw LatticeError("measure: marks lie closer than the grid's pitch: not this target");
    for (int turn = 0; turn < 3 && !(e1.x >= std::abs(e1.y)); ++turn) e1 = {e1.y, -e1.x};
    const Point2 e2{-e1.y, e1.x};
    Lattice lattice;
    lattice[{0, 0}] = {origin, seed};
    std::deque<std::pair<int, int>> queue{{0, 0}};
    const int directions[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    while (!queue.empty()) {
        const auto at = queue.front();
        queue.pop_front();
        const LatticeNode here = lattice[at];
        for (const auto& d : directions) {
            const std::pair<int, int> next{at.first + d[0], at.second + d[1]};
            if (lattice.count(next) != 0) continue;
            Point2 step{d[0] * e1.x + d[1] * e2.x, d[0] * e1.y + d[1] * e2.y};
            const auto behind = lattice.find({at.first - d[0], at.second - d[1]});
            if (behind != lattice.end() && behind->second.candidate >= 0 && here.candidate >= 0)
                step = {here.position_mm.x - behind->second.position_mm.x,
                        here.position_mm.y - behind->second.position_mm.y};
            const Point2 predicted{here.position_mm.x + step.x, here.position_mm.y + step.y};
            const long found = near.nearest(predicted, reach);
            if (found >= 0) {
                candidates[static_cast<std::size_t>(found)].taken = true;
                lattice[next] = {candidates[static_cast<std::size_t>(found)].bed_mm, found};
                queue.push_back(next);
            } else if (here.candidate >= 0) {
                lattice[next] = {predicted, -1};  // a gap: look one further through it
                queue.push_back(next);
            }
        }
    }
    return lattice;
}

LatticeExtent lattice_extent(const Lattice& lattice) {
    LatticeExtent e{1 << 30, -(1 << 30), 1 << 30, -(1 << 30)};
    for (const auto& [index, node] : lattice) {
        if (node.candidate < 0) continue;
        e.min_a = std::min(e.min_a, index.first), e.max_a = std::max(e.max_a, index.first);
        e.min_b = std::min(e.min_b, index.second), e.max_b = std::max(e.max_b, index.second);
    }
    return e;
}

}  // namespace calbox::modes
