#include "board/sim/scenes.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>
#include <stdexcept>

#include "board/sim/scene_sampling.hpp"

namespace calbox::sim {
using namespace scene_sampling;

double inside_fraction(double signed_distance_mm, Vec2 n, const double j[2][2], int subdivisions) {
    // In the sub-square's own coordinates u, v in [-1/2, 1/2] the signed distance is
    // d + g.(u, v) with g = J^T n / subdivisions; the answer is the probability that
    // g.(u, v) < -d for u, v uniform: a trapezoid's cumulative distribution.
    const double gx = (j[0][0] * n.x + j[1][0] * n.y) / subdivisions;
    const double gy = (j[0][1] * n.x + j[1][1] * n.y) / subdivisions;
    const double length = std::hypot(gx, gy);
    if (length < 1e-15) return signed_distance_mm < 0 ? 1.0 : 0.0;
    const double a = std::abs(gx) / length, b = std::abs(gy) / length;
    const double p = std::min(a, b), q = std::max(a, b);
    const double t = -signed_distance_mm / length + 0.5 * (p + q);
    if (t <= 0) return 0.0;
    if (t >= p + q) return 1.0;
    if (p < 1e-12) return t / q;
    if (t < p) return t * t / (2 * p * q);
    if (t <= q) return (t - 0.5 * p) / q;
    const double r = p + q - t;
    return 1.0 - r * r / (2 * p * q);
}

// ---------------------------------------------------------------------------------------------
// Strokes

struct StrokeScene::Index {
    double cell_mm = 1.0;
    double x0 = 0, y0 = 0;
    int nx = 0, ny = 0;
    double reference_height_mm = 0;
    // A stroke listed in a cell, with how far its outline is from the cell's centre (in the
    // plane, at the strokes' own heights): each cell's list is in that order, so that a search
    // ends at the first stroke that cannot beat the best so far.
    struct Entry {
        std::uint32_t stroke;
        double outline_from_centre_mm;
    };
    struct Cell {
        std::vector<Entry> entries;
        double farthest_height_mm = 0;  // of its strokes' ends from the reference height
    };
    std::vector<Cell> cells;

    const Cell* at(double x, double y) const {
        const int i = static_cast<int>(std::floor((x - x0) / cell_mm));
        const int k = static_cast<int>(std::floor((y - y0) / cell_mm));
        if (i < 0 || k < 0 || i >= nx || k >= ny) return nullptr;
        return &cells[static_cast<std::size_t>(k) * nx + i];
    }
};

namespace {

struct Nearest {
    double signed_distance_mm = std::numeric_limits<double>::infinity();
    Vec2 normal{1, 0};
    double width_mm = 0;
};

// Smooth value noise in [-1, 1] with unit grain: a fixed hash of the lattice, interpolated.
double value_noise(double x, double y) {
    const double fx = std::floor(x), fy = std::floor(y);
    const auto lattice = [](double i, double j) {
        auto h = static_cast<std::uint32_t>(static_cast<std::int64_t>(i)) * 73856093U ^
                 static_cast<std::uint32_t>(static_cast<std::int64_t>(j)) * 19349663U;
        h ^= h >> 13;
        h *= 0x5bd1e995U;
        h ^= h >> 15;
        return static_cast<double>(h % 2001U) / 1000.0 - 1.0;
    };
    const auto smooth = [](double t) { return t * t * (3 - 2 * t); };
    const double tx = smooth(x - fx), ty = smooth(y - fy);
    const double top = lattice(fx, fy) + tx * (lattice(fx + 1, fy) - lattice(fx, fy));
    const double bottom =
        lattice(fx, fy + 1) + tx * (lattice(fx + 1, fy + 1) - lattice(fx, fy + 1));
    return top + ty * (bottom - top);
}

double closest_parameter(const StrokeSegment& s, double x, double y) {
    const double dx = s.b_mm.x - s.a_mm.x, dy = s.b_mm.y - s.a_mm.y;
    const double l2 = dx * dx + dy * dy;
    if (l2 < 1e-24) return 0.0;
    return std::clamp(((x - s.a_mm.x) * dx + (y - s.a_mm.y) * dy) / l2, 0.0, 1.0);
}

// From the stroke's centreline at parameter t to (x, y).
Vec2 offset_from_centreline(const StrokeSegment& s, double t, double x, double y) {
    return {x - (s.a_mm.x + t * (s.b_mm.x - s.a_mm.x)), y - (s.a_mm.y + t * (s.b_mm.y - s.a_mm.y))};
}

}  // namespace

double stroke_footprint_mm(const CameraIntrinsics& camera, double distance_mm) {
    return 3 * distance_mm / camera.fx;
}

StrokeScene::StrokeScene(std::vector<StrokeSegment> strokes, double bed_albedo,
                         double material_albedo, int supersample, double footprint_mm,
                         const StrokeSurface& surface)
    : strokes_(std::move(strokes)),
      index_(std::make_unique<Index>()),
      bed_albedo_(bed_albedo),
      material_albedo_(material_albedo),
      supersample_(std::max(1, supersample)),
      surface_(surface) {
    if (!(surface.bed_texture_grain_mm > 0) || surface.bed_texture < 0 || surface.gloss < 0) {
        throw std::invalid_argument("a bed's grain must be positive, its texture and gloss >= 0");
    }
    {
        // The camera looks straight down; the light comes from its azimuth and elevation.
        const double az = radians(surface.light_azimuth_deg);
        const double el = radians(surface.light_elevation_deg);
        const Vec3 light{std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
        const Vec3 half = (light + Vec3{0, 0, 1}).normalized();
        gloss_half_vector_xy_ = {half.x, half.y};
        gloss_half_vector_z_ = half.z;
    }
    if (strokes_.empty()) return;
    double zmin = 1e300, zmax = -1e300, xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
    double zsum = 0;
    for (const auto& s : strokes_) {
        for (const Vec3& p : {s.a_mm, s.b_mm}) {
            zmin = std::min(zmin, p.z);
            zmax = std::max(zmax, p.z);
            zsum += p.z;
        }
    }
    auto& ix = *index_;
    ix.reference_height_mm = zsum / (2.0 * strokes_.size());
    // A stroke is listed in every cell its outline, widened by a pixel footprint and by the
    // drift of a ray across the stroke heights, can reach.
    if (!(footprint_mm > 0)) throw std::invalid_argument("a pixel footprint must be positive");
    ix.cell_mm = std::clamp(2 * footprint_mm, 0.1, 1.0);
    const double drift = (zmax - zmin) * 0.8 + footprint_mm;
    for (const auto& s : strokes_) {
        const double m = s.width_mm / 2 + drift;
        xmin = std::min({xmin, s.a_mm.x - m, s.b_mm.x - m});
        xmax = std::max({xmax, s.a_mm.x + m, s.b_mm.x + m});
        ymin = std::min({ymin, s.a_mm.y - m, s.b_mm.y - m});
        ymax = std::max({ymax, s.a_mm.y + m, s.b_mm.y + m});
    }
    ix.x0 = xmin;
    ix.y0 = ymin;
    ix.nx = static_cast<int>(std::ceil((xmax - xmin) / ix.cell_mm)) + 1;
    ix.ny = static_cast<int>(std::ceil((ymax - ymin) / ix.cell_mm)) + 1;
    ix.cells.resize(static_cast<std::size_t>(ix.nx) * ix.ny);
    for (std::uint32_t n = 0; n < strokes_.size(); ++n) {
        const auto& s = strokes_[n];
        const double m = s.width_mm / 2 + drift;
        const int i0 = static_cast<int>((std::min(s.a_mm.x, s.b_mm.x) - m - ix.x0) / ix.cell_mm);
        const int i1 = static_cast<int>((std::max(s.a_mm.x, s.b_mm.x) + m - ix.x0) / ix.cell_mm);
        const int k0 = static_cast<int>((std::min(s.a_mm.y, s.b_mm.y) - m - ix.y0) / ix.cell_mm);
        const int k1 = static_cast<int>((std::max(s.a_mm.y, s.b_mm.y) + m - ix.y0) / ix.cell_mm);
        // Cells whose centre is farther than half a diagonal plus the margin are skipped, so
        // long diagonal strokes do not fill their whole bounding box.
        const double reach = m + ix.cell_mm * 0.7072;
        for (int k = std::max(0, k0); k <= std::min(ix.ny - 1, k1); ++k) {
            for (int i = std::max(0, i0); i <= std::min(ix.nx - 1, i1); ++i) {
                const double cx = ix.x0 + (i + 0.5) * ix.cell_mm,
                             cy = ix.y0 + (k + 0.5) * ix.cell_mm;
                const Vec2 e = offset_from_centreline(s, closest_parameter(s, cx, cy), cx, cy);
                if (e.x * e.x + e.y * e.y <= reach * reach) {
                    auto& cell = ix.cells[static_cast<std::size_t>(k) * ix.nx + i];
                    cell.entries.push_back({n, std::hypot(e.x, e.y) - s.width_mm / 2});
                    cell.farthest_height_mm = std::max(
                        {cell.farthest_height_mm, std::abs(s.a_mm.z - ix.reference_height_mm),
                         std::abs(s.b_mm.z - ix.reference_height_mm)});
                }
            }
        }
    }
    for (auto& cell : ix.cells) {
        std::stable_sort(cell.entries.begin(), cell.entries.end(),
                         [](const Index::Entry& a, const Index::Entry& b) {
                             return a.outline_from_centre_mm < b.outline_from_centre_mm;
                         });
    }
}

StrokeScene::~StrokeScene() = default;

double StrokeScene::bed_at(Vec2 p) const {
    if (surface_.bed_texture == 0) return bed_albedo_;
    // Two octaves of grain, the finer at half the size and half the swing.
    const double g = surface_.bed_texture_grain_mm;
    const double n =
        (2 * value_noise(p.x / g, p.y / g) + value_noise(2 * p.x / g + 17.5, 2 * p.y / g - 3.25)) /
        3;
    return std::clamp(bed_albedo_ * (1 + surface_.bed_texture * n), 0.0, 1.0);
}

double StrokeScene::albedo(const Footprint& f) const {
    const double bed = bed_at(f.centre_mm);
    if (strokes_.empty()) return bed;
    const Index& ix = *index_;
    const auto nearest = [&](Vec2 p) {
        // The best stroke so far is chosen on sqrt(dx^2 + dy^2), within 1e-14 mm of hypot's
        // figure and a tenth of hypot's cost; a near tie (within kTieMm) is settled on hypot
        // itself, and the winner's distance and normal are hypot's: the choice is the one the
        // exact comparisons make, so the photos are bit for bit what they were without it.
        constexpr double kTieMm = 1e-9;
        const StrokeSegment* best_stroke = nullptr;
        std::uint32_t best_index = 0;
        Vec2 best_offset{0, 0};
        double best_fast_mm = std::numeric_limits<double>::infinity();
        const auto exact_signed_distance = [](const StrokeSegment& s, Vec2 e) {
            return std::hypot(e.x, e.y) - s.width_mm / 2;
        };
        // A stroke whose centreline is `e` away, give or take `slack`, clearly farther than the
        // best so far: the square settles it without a square root, and the nanometre of
        // margin, far above rounding, leaves every close call to the comparisons below.
        const auto clearly_farther = [&best_fast_mm](const StrokeSegment& s, Vec2 e, double slack) {
            const double beats = best_fast_mm + s.width_mm / 2 + slack + 1e-6;
            return beats <= 0 || e.x * e.x + e.y * e.y > beats * beats;
        };
        const double zr = ix.reference_height_mm;
        // At least the ray's drift per mm of height (hypot's bound, without its cost).
        const double shift_bound = std::abs(f.shift_per_height.x) + std::abs(f.shift_per_height.y);
        const auto* cell = ix.at(p.x + f.shift_per_height.x * zr, p.y + f.shift_per_height.y * zr);
        if (cell == nullptr) return Nearest{};
        // The point at the reference height lies within half the cell's diagonal of its centre,
        // and the ray moves it by at most shift_bound per mm of height: a stroke's outline is no
        // nearer than its distance from the centre less these (and a nanometre for rounding).
        const double nearer_by_at_most_mm =
            ix.cell_mm * 0.7072 + shift_bound * cell->farthest_height_mm + 1e-6;
        for (const auto& [n, outline_from_centre_mm] : cell->entries) {
            // The rest of the list is farther still: none of it can beat the best.
            if (outline_from_centre_mm - nearer_by_at_most_mm > best_fast_mm + kTieMm) break;
            const auto& s = strokes_[n];
            // Where the ray meets this stroke's top: find the stroke height near the ray,
            // move along the ray to it, and measure again.
            double qx = p.x + f.shift_per_height.x * zr, qy = p.y + f.shift_per_height.y * zr;
            double t = closest_parameter(s, qx, qy);
            // Distance to a segment moves no faster than the point does: along the ray, between
            // the reference height and any of this stroke's, by at most this. A stroke that far
            // beyond the best so far cannot become it: its refinement is skipped.
            const double slack =
                shift_bound * std::max(std::abs(s.a_mm.z - zr), std::abs(s.b_mm.z - zr));
            if (clearly_farther(s, offset_from_centreline(s, t, qx, qy), slack)) continue;
            double z_used = zr;
            for (int pass = 0; pass < 2; ++pass) {
                const double z = s.a_mm.z + t * (s.b_mm.z - s.a_mm.z);
                // The same height gives the same point and the same parameter again (a flat
                // stroke, most of them): nothing left to refine.
                if (z == z_used) break;
                z_used = z;
                qx = p.x + f.shift_per_height.x * z;
                qy = p.y + f.shift_per_height.y * z;
                t = closest_parameter(s, qx, qy);
            }
            const Vec2 e = offset_from_centreline(s, t, qx, qy);
            if (clearly_farther(s, e, 0)) continue;
            const double fast_mm = std::sqrt(e.x * e.x + e.y * e.y) - s.width_mm / 2;
            if (fast_mm > best_fast_mm + kTieMm) continue;
            if (fast_mm >= best_fast_mm - kTieMm) {
                // A near tie: hypot's figures decide, and of two equal the stroke listed first
                // in the scene, as a search in the scene's order keeps it.
                const double exact = exact_signed_distance(s, e);
                const double best_exact = exact_signed_distance(*best_stroke, best_offset);
                if (exact > best_exact || (exact == best_exact && n > best_index)) continue;
            }
            best_stroke = &s;
            best_index = n;
            best_offset = e;
            best_fast_mm = fast_mm;
        }
        Nearest best;
        if (best_stroke == nullptr) return best;
        const StrokeSegment& s = *best_stroke;
        const double dx = best_offset.x, dy = best_offset.y;
        const double d = std::hypot(dx, dy);
        best.signed_distance_mm = d - s.width_mm / 2;
        best.width_mm = s.width_mm;
        if (d > 1e-12) {
            best.normal = {dx / d, dy / d};
        } else {
            const double l = std::hypot(s.b_mm.x - s.a_mm.x, s.b_mm.y - s.a_mm.y);
            best.normal = l > 1e-12 ? Vec2{-(s.b_mm.y - s.a_mm.y) / l, (s.b_mm.x - s.a_mm.x) / l}
                                    : Vec2{1, 0};
        }
        return best;
    };
    const Nearest centre = nearest(f.centre_mm);
    // Most pixels see bare bed, with no stroke near: the footprint's reach is not needed there.
    if (std::isinf(centre.signed_distance_mm)) return bed;
    const double reach = std::hypot(f.jacobian[0][0], f.jacobian[1][0]) +
                         std::hypot(f.jacobian[0][1], f.jacobian[1][1]);
    double coverage;
    if (centre.signed_distance_mm > reach) {
        coverage = 0;
    } else if (centre.signed_distance_mm < -reach) {
        coverage = 1;
    } else {
        coverage = average_over_subpixels(f, supersample_, [&](Vec2 q) {
            const Nearest n = nearest(q);
            if (!std::isfinite(n.signed_distance_mm)) return 0.0;
            return inside_fraction(n.signed_distance_mm, n.normal, f.jacobian, supersample_);
        });
    }
    double highlight = 0;
    if (surface_.gloss > 0 && centre.signed_distance_mm < 0 && centre.width_mm > 0) {
        // A round strand's top: the surface normal leans out by the fraction of the half-width
        // one is across it. The highlight is a lobe around the half vector (about 8 degrees),
        // spread over the pixel's footprint with its energy kept.
        const double half_width = centre.width_mm / 2;
        const double across =
            std::clamp((centre.signed_distance_mm + half_width) / half_width, 0.0, 1.0);
        const double nz = std::sqrt(1 - across * across);
        const double cosine = across * (centre.normal.x * gloss_half_vector_xy_.x +
                                        centre.normal.y * gloss_half_vector_xy_.y) +
                              nz * gloss_half_vector_z_;
        const double angle = std::acos(std::clamp(cosine, -1.0, 1.0));
        const double lobe = radians(8.0);
        const double footprint = reach / 2 / half_width / std::sqrt(12.0);
        const double spread = std::hypot(lobe, footprint);
        highlight =
            surface_.gloss * lobe / spread * std::exp(-0.5 * angle * angle / (spread * spread));
    }
    return bed + coverage * (material_albedo_ - bed) + coverage * highlight;
}

// ---------------------------------------------------------------------------------------------
// A sheet of stock

SheetScene::SheetScene(const StockSheet& sheet, int supersample)
    : sheet_(sheet), supersample_(std::max(1, supersample)) {
    if (!(sheet.width_mm > 0 && sheet.depth_mm > 0))
        throw std::invalid_argument("a sheet needs a width and a depth");
    const double a = radians(sheet.angle_deg);
    along_ = {std::cos(a), std::sin(a)};
    across_ = {-std::sin(a), std::cos(a)};
}

std::array<Vec2, 4> SheetScene::corners() const {
    const Vec2 c = sheet_.corner_mm;
    const double w = sheet_.width_mm, d = sheet_.depth_mm;
    return {c, Vec2{c.x + w * along_.x, c.y + w * along_.y},
            Vec2{c.x + w * along_.x + d * across_.x, c.y + w * along_.y + d * across_.y},
            Vec2{c.x + d * across_.x, c.y + d * across_.y}};
}

double SheetScene::albedo(const Footprint& f) const {
    // The point in the sheet's own frame; the four edges' outward normals on the bed.
    const auto local = [&](Vec2 p) {
        const double dx = p.x - sheet_.corner_mm.x, dy = p.y - sheet_.corner_mm.y;
        return Vec2{dx * along_.x + dy * along_.y, dx * across_.x + dy * across_.y};
    };
    const auto nearest_edge = [&](Vec2 q, Vec2* normal) {
        // Signed distance (negative inside) to the edge whose half-plane decides: the largest.
        const Vec2 l = local(q);
        const double d[4] = {-l.y, l.x - sheet_.width_mm, l.y - sheet_.depth_mm, -l.x};
        const Vec2 n[4] = {{-across_.x, -across_.y}, along_, across_, {-along_.x, -along_.y}};
        int k = 0;
        for (int i = 1; i < 4; ++i)
            if (d[i] > d[k]) k = i;
        *normal = n[k];
        return d[k];
    };
    const auto mix = [&](double on_sheet) {
        return on_sheet * sheet_.sheet_albedo + (1 - on_sheet) * sheet_.bed_albedo;
    };
    const Extent e = half_extent(f);
    Vec2 normal;
    const double centre = nearest_edge(f.centre_mm, &normal);
    if (std::abs(centre) > e.x_mm + e.y_mm) return mix(centre < 0 ? 1.0 : 0.0);
    const int s = supersample_;
    return average_over_subpixels(f, s, [&](Vec2 q) {
        Vec2 n;
        const double d = nearest_edge(q, &n);
        return mix(inside_fraction(d, n, f.jacobian, s));
    });
}

double distance_to_polyline(Vec2 p, const std::vector<Vec2>& line) {
    double best = 1e300;
    for (std::size_t k = 0; k + 1 < line.size(); ++k) {
        const double dx = line[k + 1].x - line[k].x, dy = line[k + 1].y - line[k].y;
        const double t = std::clamp(
            ((p.x - line[k].x) * dx + (p.y - line[k].y) * dy) / (dx * dx + dy * dy), 0.0, 1.0);
        best = std::min(best, std::hypot(p.x - line[k].x - t * dx, p.y - line[k].y - t * dy));
    }
    return best;
}

}  // namespace calbox::sim
