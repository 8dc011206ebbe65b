#include "core/modes/delta.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <utility>

#include "core/each_on_all_cores.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/geometry/line_fit.hpp"
#include "core/geometry/placement.hpp"
#include "core/models/delta.hpp"
#include "core/number_text.hpp"
#include "core/vision/edge_kernel.hpp"
#include "core/vision/exposure.hpp"
#include "core/vision/strand_ring.hpp"

namespace calbox::modes {
namespace {

// How far a marker may stand from where the target lays it, relative to the others, before the
// photo is taken for another artifact's.
constexpr double kLayoutToleranceMm = 4.0;

// Exposure that leaves no edge to measure, in the limits' words. Each is what a photo of white
// or grey filament on a dark or light sheet, lit by the box's lamp, stays well clear of.
struct ExposureLimits {
    // The print's brightest part must reach this: below it the edges' steps are a few tens of
    // counts, and the sensor's noise (2-3 counts) and the JPEG's rounding become their size.
    double brightest_at_least_dn = 60;
    // A pixel at or above this is taken as clipped: sensor curves and JPEG flatten the last few
    // counts before 255.
    double clipped_from_dn = 250;
    // A clipped bright side moves its edges towards the dark side; up to this share of the bright
    // part (or of the frame) is a highlight or a glint, past it the exposure is wrong.
    double clipped_share_at_most = 0.2;
};

void check_exposure(const vision::GrayView& image, std::size_t frame,
                    const ExposureLimits& limits = {}) {
    const std::string which = "photo " + std::to_string(frame + 1);
    // One pass over the photo: its histogram gives the brightest level, Otsu's split and the
    // counts above it (three passes and two masks of the frame's size before).
    const cv::Mat view(image.height_px, image.width_px, CV_8UC1,
                       const_cast<std::uint8_t*>(image.pixels),
                       static_cast<std::size_t>(image.stride_bytes));
    cv::Mat counts;
    const int bins = 256;
    const float range[] = {0, 256};
    const float* ranges[] = {range};
    const int channel = 0;
    cv::calcHist(&view, 1, &channel, cv::Mat(), counts, 1, &bins, ranges);
    std::array<double, 256> histogram{};
    for (int level = 0; level < bins; ++level)
        histogram[static_cast<std::size_t>(level)] = counts.at<float>(level);
    int brightest = bins - 1;
    while (brightest > 0 && histogram[static_cast<std::size_t>(brightest)] == 0) --brightest;
    if (brightest < limits.brightest_at_least_dn)
        throw MeasureError(which + " is under-exposed: nothing in it is brighter than " +
                           std::to_string(brightest) + " of 255");
    // Bright and dark split where Otsu's method puts it: the printed lines and the bed.
    const int split = vision::otsu_level(histogram);
    const auto total = static_cast<double>(view.total());
    double bright = 0, clipped = 0;
    for (int level = 0; level < bins; ++level) {
        const double n = histogram[static_cast<std::size_t>(level)];
        if (level > split) bright += n;
        if (level >= limits.clipped_from_dn) clipped += n;
    }
    if (clipped > limits.clipped_share_at_most * total ||
        (bright > 0 && clipped > limits.clipped_share_at_most * bright)) {
        throw MeasureError(which + " is over-exposed: " +
                           std::to_string(static_cast<int>(100 * clipped / bright)) +
                           " % of its bright part is clipped white");
    }
}

// Where a printed surface lies on the bed frame the photos are mapped in: the machine's actual
// nozzle position for a commanded point, placed on the bed, grown with the bed.
struct SurfaceModel {
    std::optional<models::DeltaGeometry> truth;  // fitted; without it, commanded = actual
    models::DeltaGeometry firmware;
    geometry::RigidPlacement placement;  // machine frame -> bed frame
    double bed_scale = 1;

    geometry::Point3 on_bed(geometry::Point3 commanded) const {
        geometry::Point3 p = commanded;
        if (truth) p = models::actual_position_mm(*truth, firmware, commanded);
        const geometry::Point2 placed = placement.apply({p.x, p.y});
        return {bed_scale * placed.x, bed_scale * placed.y, truth ? p.z : commanded.z};
    }
};

// How a bar's end tick is profiled and when it is not one, with the reasons.
struct TickLimits {
    // Profiles stay this far inside the tick's ends (where the nozzle starts and stops it,
    // rounded and blobbed), one every this many millimetres along it.
    double end_clearance_mm = 0.6;
    double profile_step_mm = 0.25;
    // A tick seen in fewer profiles than this share is cut, smeared or hidden.
    double min_profile_share = 2.0 / 3.0;
    // A tick's centreline is straight to a few micrometres; a blob, a gap or a stray strand is
    // not a tick to measure.
    double max_rms_mm = 0.05;
    vision::StrandRingLimits strand;  // how each profile finds its two edges
};

// One end tick of a bar in one photo: the centreline of the strand on the bed frame (at
// `height_mm`), from its two edges on profiles along the bar.
struct TickLine {
    geometry::Line line;
    std::vector<geometry::Point2> points;
};

// Without a tick, `why_not` says what was missing. `outward`: along the bar, away from it.
std::optional<TickLine> measure_tick(const vision::GrayView& image,
                                     const geometry::CameraModel& camera,
                                     const geometry::BedPlane& plane, geometry::Point2 expected,
                                     geometry::Point2 outward, double height_mm,
                                     double half_length_mm, double strand_width_mm,
                                     std::string& why_not, const TickLimits& limits = {}) {
    const geometry::Point2 across{-outward.y, outward.x};
    // From a little inside its expected centreline (short of the bar's end face, a gap away)
    // to past its commanded outer edge: as the rings are profiled.
    const double from_mm = -limits.strand.centre_uncertainty_mm;
    const double to_mm = strand_width_mm / 2 + limits.strand.reach_outside_mm;
    const double reach = half_length_mm - limits.end_clearance_mm;
    const int profiles = static_cast<int>(std::floor(2 * reach / limits.profile_step_mm)) + 1;
    std::vector<geometry::Point3> stations;
    for (int k = 0; k < profiles; ++k) {
        const double t = -reach + k * limits.profile_step_mm;
        for (const double d : {from_mm, to_mm})
            stations.push_back({expected.x + across.x * t + outward.x * d,
                                expected.y + across.y * t + outward.y * d, height_mm});
    }
    const auto px = geometry::project_points(camera, plane.bed_to_camera, stations);
    std::vector<geometry::Point2> centres_px;
    for (std::size_t k = 0; k + 1 < px.size(); k += 2) {
        const auto from = px[k];
        const auto to = px[k + 1];
        const double px_per_mm = std::hypot(to.x - from.x, to.y - from.y) / (to_mm - from_mm);
        const auto crossing =
            vision::strand_across(image, from, to, px_per_mm, strand_width_mm, limits.strand);
        if (crossing) centres_px.push_back(crossing->centre_px);
    }
    if (static_cast<double>(centres_px.size()) < limits.min_profile_share * profiles) {
        why_not = "the strand in only " + std::to_string(centres_px.size()) + " of " +
                  std::to_string(profiles) + " profiles across it";
        return std::nullopt;
    }
    TickLine tick;
    for (const auto& p : geometry::pixels_to_bed(camera, plane, centres_px, height_mm))
        tick.points.push_back({p.x, p.y});
    tick.line = geometry::fit_line(tick.points);
    const double rms = geometry::line_rms(tick.line, tick.points);
    if (rms > limits.max_rms_mm) {
        why_not = "not straight: its centreline points lie " + number_text("%.3f", rms) +
                  " mm RMS from a line, " + number_text("%g", limits.max_rms_mm) + " allowed";
        return std::nullopt;
    }
    return tick;
}

// The printed surface, from a fit of the marker corners: on an uncalibrated printer the bed's
// dome lifts the outer features by tenths of a millimetre, which seen from 40 cm moves them by
// hundredths. Each corner is moved along its ray to its fitted height, so the positions written
// are where the material is; the fit's own parallax terms then see nothing left to move. When
// the fit fails, the nominal height stays and measurement says so.
SurfaceModel fit_surface(const models::MachineFile& machine, DeltaMeasurement& out) {
    SurfaceModel surface;
    surface.firmware = *machine.delta;
    surface.bed_scale = out.bed_scale;
    try {
        // Only the estimate is wanted here, whatever correction it would lead to; measurements
        // the geometry cannot explain leave the nominal height.
        const auto fit = solve::estimate_delta_geometry(machine, out.features, {});
        solve::check_residual(fit, {});
        surface.truth = fit.estimate;
        surface.placement = fit.placement;
        out.heights_from_fit = true;
        for (auto& f : out.features) {
            if (f.height_measured) continue;
            const double z =
                models::actual_position_mm(fit.estimate, *machine.delta, f.commanded_mm).z;
            const double dz = z - f.seen_at_height_mm;
            f.measured_mm.x += dz * f.shift_per_height.x;
            f.measured_mm.y += dz * f.shift_per_height.y;
            f.seen_at_height_mm = z;
        }
    } catch (const solve::FitError& e) {
        out.heights_fallback = std::string("the surface fit failed (") + e.what() +
                               "): bar ends mapped at the target's top, " +
                               number_text("%.2f", out.target.top_height_mm) + " mm";
        std::vector<geometry::Point2> commanded, measured;
        for (const auto& f : out.features)
            commanded.push_back({f.commanded_mm.x, f.commanded_mm.y}),
                measured.push_back(f.measured_mm);
        if (commanded.size() >= 2) {
            surface.placement = geometry::best_rigid_placement(commanded, measured);
        }
    }
    return surface;
}

// The classic bars, each between its end ticks' centrelines, mapped at the surface's height
// there, along the bar's centreline as the surface model places it.
void measure_bars(const models::MachineFile& machine, const geometry::CameraModel& camera,
                  const geometry::BedPlane& plane, const std::vector<vision::GrayView>& frames,
                  const SurfaceModel& surface, DeltaMeasurement& out) {
    const double top = out.target.top_height_mm;
    for (const auto& bar : out.target.bars) {
        const auto near = surface.on_bed({bar.ticks_mm[0].x, bar.ticks_mm[0].y, top});
        const auto far = surface.on_bed({bar.ticks_mm[1].x, bar.ticks_mm[1].y, top});
        const double span = std::hypot(far.x - near.x, far.y - near.y);
        const geometry::Point2 axis{(far.x - near.x) / span, (far.y - near.y) / span};
        const geometry::Line centreline{{near.x, near.y}, axis};
        std::vector<double> lengths;
        double sigma_sum = 0;
        std::array<geometry::Point3, 2> ticks_seen{};
        std::string why_not;
        for (std::size_t f = 0; f < frames.size(); ++f) {
            std::array<std::optional<geometry::Point2>, 2> crossings;
            double sigma2 = 0;
            for (std::size_t end = 0; end < 2; ++end) {
                const auto& at = end == 0 ? near : far;
                const double sign = end == 0 ? -1 : 1;
                std::string tick_why;
                const auto tick = measure_tick(frames[f], camera, plane, {at.x, at.y},
                                               {sign * axis.x, sign * axis.y}, at.z,
                                               bar.width_mm / 2, machine.line_width_mm, tick_why);
                if (!tick) {
                    why_not = std::string("bar ") + bar.tower + ": photo " + std::to_string(f + 1) +
                              ": its " + (end == 0 ? "inner" : "outer") + " end tick: " + tick_why;
                    break;
                }
                crossings[end] = geometry::intersect(tick->line, centreline);
                if (!crossings[end]) {
                    why_not = std::string("bar ") + bar.tower + ": photo " + std::to_string(f + 1) +
                              ": its end tick runs along the bar";
                    break;
                }
                const double s = geometry::line_sigma_at(tick->line, tick->points, *crossings[end]);
                sigma2 += s * s;
            }
            if (!crossings[0] || !crossings[1]) break;
            if (lengths.empty()) {
                ticks_seen = {geometry::Point3{crossings[0]->x, crossings[0]->y, near.z},
                              geometry::Point3{crossings[1]->x, crossings[1]->y, far.z}};
            }
            lengths.push_back(
                std::hypot(crossings[1]->x - crossings[0]->x, crossings[1]->y - crossings[0]->y) /
                out.bed_scale);
            sigma_sum += sigma2;
        }
        if (lengths.size() != frames.size()) {  // not measurable in every photo
            out.bars_unmeasured.push_back(why_not);
            continue;
        }
        BarLengthMeasurement m;
        m.tower = bar.tower;
        m.commanded_from_mm = std::hypot(bar.ticks_mm[0].x, bar.ticks_mm[0].y);
        m.commanded_to_mm = std::hypot(bar.ticks_mm[1].x, bar.ticks_mm[1].y);
        m.commanded_mm = bar.length_mm();
        const double k = static_cast<double>(lengths.size());
        double mean = 0;
        for (double l : lengths) mean += l;
        mean /= k;
        double scatter = 0;
        for (double l : lengths) scatter += (l - mean) * (l - mean);
        m.measured_mm = mean;
        // The mapping's own scale (the plane calibration) adds a floor of about 0.003 mm.
        const double per_frame = std::sqrt(sigma_sum / k + 0.003 * 0.003);
        m.sigma_mm = std::max(per_frame, k > 1 ? std::sqrt(scatter / (k - 1)) : 0.0) / std::sqrt(k);
        m.surface_height_mm = (near.z + far.z) / 2;
        m.ticks_seen_mm = ticks_seen;
        out.bars.push_back(m);
    }
}

// The target's markers a photo did not show, told apart: those it should show (the placement of
// the ones it did puts all four corners inside the frame), which were there but could not be
// read (a squashed, smeared or missing first layer), and those outside the frame.
struct MissingMarkers {
    std::vector<std::string> unread;  // "marker 7 near (1234, 567) px"
    std::size_t outside_frame = 0;
};
MissingMarkers missing_markers(const targets::DeltaTarget& target,
                               const std::vector<vision::DetectedMarker>& found,
                               const geometry::RigidPlacement& placement,
                               const geometry::CameraModel& camera,
                               const geometry::BedPlane& plane) {
    MissingMarkers out;
    for (const auto& marker : target.markers) {
        const bool seen = std::any_of(found.begin(), found.end(),
                                      [&](const auto& m) { return m.id == marker.id; });
        if (seen) continue;
        std::vector<geometry::Point3> corners;
        for (const auto& c : marker.corners_mm) {
            const auto p = placement.apply(c);
            corners.push_back({p.x, p.y, target.top_height_mm});
        }
        const auto px = geometry::project_points(camera, plane.bed_to_camera, corners);
        const bool inside = std::all_of(px.begin(), px.end(), [&](const geometry::Point2& q) {
            return q.x >= 0 && q.y >= 0 && q.x <= camera.image_width - 1 &&
                   q.y <= camera.image_height - 1;
        });
        if (!inside) {
            ++out.outside_frame;
            continue;
        }
        char where[96];
        std::snprintf(where, sizeof where, "marker %d near (%.0f, %.0f) px", marker.id,
                      (px[0].x + px[1].x + px[2].x + px[3].x) / 4,
                      (px[0].y + px[1].y + px[2].y + px[3].y) / 4);
        out.unread.emplace_back(where);
    }
    return out;
}

// Where the target's markers stand in the photo by the bed's pose from set-up, and how large:
// ArUco's thresholds and contours then run on a window round them (each grown by a marker's side
// and the layout's tolerance: the detector needs the quiet zone round a marker, and an
// uncalibrated printer puts them a few millimetres off), scaled down as far as their size allows,
// not on the whole 12 MP frame. Nothing is set when the target lies outside the photo.
void look_where_the_target_stands(vision::MarkerOptions& options,
                                  const targets::DeltaTarget& target,
                                  const geometry::CameraModel& camera,
                                  const geometry::BedPlane& plane) {
    const double grow_mm = 2 * target.marker_half_mm + kLayoutToleranceMm;
    std::vector<geometry::Point3> grown, corners;
    for (const auto& marker : target.markers) {
        for (const double dx : {-1.0, 1.0})
            for (const double dy : {-1.0, 1.0})
                grown.push_back({marker.centre_mm.x + dx * (target.marker_half_mm + grow_mm),
                                 marker.centre_mm.y + dy * (target.marker_half_mm + grow_mm),
                                 target.top_height_mm});
        for (const auto& c : marker.corners_mm) corners.push_back({c.x, c.y, target.top_height_mm});
    }
    const auto px = geometry::project_points(camera, plane.bed_to_camera, grown);
    double x0 = px.front().x, x1 = x0, y0 = px.front().y, y1 = y0;
    for (const auto& p : px) {
        if (!std::isfinite(p.x) || !std::isfinite(p.y)) return;
        x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
        y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
    }
    x0 = std::max(x0, 0.0), y0 = std::max(y0, 0.0);
    x1 = std::min(x1, camera.image_width - 1.0), y1 = std::min(y1, camera.image_height - 1.0);
    if (x1 <= x0 || y1 <= y0) return;
    const auto side = geometry::project_points(camera, plane.bed_to_camera, corners);
    double smallest_px = std::numeric_limits<double>::max();
    for (std::size_t m = 0; m + 3 < side.size(); m += 4)
        for (std::size_t k = 0; k < 4; ++k)
            smallest_px =
                std::min(smallest_px, std::hypot(side[m + (k + 1) % 4].x - side[m + k].x,
                                                 side[m + (k + 1) % 4].y - side[m + k].y));
    std::vector<int> ids;
    for (const auto& marker : target.markers) ids.push_back(marker.id);
    options.windows.push_back({static_cast<int>(std::floor(x0)), static_cast<int>(std::floor(y0)),
                               static_cast<int>(std::ceil(x1 - std::floor(x0))) + 1,
                               static_cast<int>(std::ceil(y1 - std::floor(y0))) + 1, ids});
    // A printed marker squashed or tilted shows smaller than laid out: half its size still found.
    constexpr double kSmallestShare = 0.5;
    if (std::isfinite(smallest_px)) options.smallest_side_px = kSmallestShare * smallest_px;
}

std::string joined(const std::vector<std::string>& parts) {
    std::string text;
    for (const auto& part : parts) text += (text.empty() ? "" : ", ") + part;
    return text;
}

}  // namespace

std::string corner_feature_id(int marker_id, int corner) {
    std::string id = "m";
    id += std::to_string(marker_id);
    id += 'c';
    id += std::to_string(corner);
    return id;
}

namespace {

// Per corner, what the frames that saw it gave.
struct CornerSightings {
    std::vector<geometry::Point3> on_bed;  // at the strand's height each frame measured
    std::vector<geometry::Point3> at_top;  // at the target's top, for a height unmeasured
    int heights_unmeasured = 0;            // frames that could not tell its strand's width
    geometry::Point2 shift;                // bed mm per mm of height along the ray
    double edge_variance_sum = 0;    // of each frame's centreline-fit uncertainty, in bed mm^2
    double height_variance_sum = 0;  // of each frame's strand height, mm^2
    int free_beads = 0;              // frames whose strand there was a free bead
    int scraped = 0;                 // frames whose strand there was scraped
};
using Sightings = std::map<std::pair<int, int>, CornerSightings>;  // by marker id and corner

// One photo's markers of this target: looked for where the target should stand; the whole photo
// only when that misses one of them (the bed moved since set-up, a marker out of frame, a foreign
// artifact), so the refusals below see what the whole photo shows. Refused when it shows none,
// or mostly another artifact's.
std::vector<vision::DetectedMarker> target_markers_in(const vision::GrayView& frame,
                                                      const std::string& photo_name,
                                                      const vision::MarkerOptions& options,
                                                      std::size_t target_markers) {
    auto found = vision::detect_markers(frame, options);
    if (found.empty())
        throw MeasureError(photo_name + " shows no " + options.dictionary + " markers");
    const auto foreign_id = [&](const auto& m) { return m.id >= static_cast<int>(target_markers); };
    if (std::count_if(found.begin(), found.end(), foreign_id) * 2 > static_cast<long>(found.size()))
        throw MeasureError(photo_name + " shows markers that are not this machine's delta target");
    found.erase(std::remove_if(found.begin(), found.end(), foreign_id), found.end());
    return found;
}

// Each marker's corners on the bed at the target's top: for the layout and the scale.
std::vector<std::vector<geometry::Point3>> corners_at_top(
    const std::vector<vision::DetectedMarker>& found, const geometry::CameraModel& camera,
    const geometry::BedPlane& plane, double top_height_mm) {
    std::vector<std::vector<geometry::Point3>> on_bed;
    for (const auto& m : found) {
        const std::vector<geometry::Point2> corners(m.corners.begin(), m.corners.end());
        on_bed.push_back(geometry::pixels_to_bed(camera, plane, corners, top_height_mm));
    }
    return on_bed;
}

// The markers must lie as this target lays them out, give or take what an uncalibrated printer
// does to it: another ArUco artifact (a board, another machine's target) does not. The target's
// place on the bed, from two markers up.
std::optional<geometry::RigidPlacement> layout_on_bed(
    const std::vector<vision::DetectedMarker>& found,
    const std::vector<std::vector<geometry::Point3>>& on_bed, const targets::DeltaTarget& target,
    std::size_t frame) {
    if (found.size() < 2) return std::nullopt;
    std::vector<geometry::Point2> laid, seen_centres;
    for (std::size_t i = 0; i < found.size(); ++i) {
        laid.push_back(target.markers[static_cast<std::size_t>(found[i].id)].centre_mm);
        const auto& bed = on_bed[i];
        seen_centres.push_back({(bed[0].x + bed[1].x + bed[2].x + bed[3].x) / 4,
                                (bed[0].y + bed[1].y + bed[2].y + bed[3].y) / 4});
    }
    const auto placement = geometry::best_rigid_placement(laid, seen_centres);
    double worst = 0;
    for (std::size_t i = 0; i < laid.size(); ++i) {
        const auto p = placement.apply(laid[i]);
        worst = std::max(worst, std::hypot(p.x - seen_centres[i].x, p.y - seen_centres[i].y));
    }
    if (worst > kLayoutToleranceMm) {
        char why[200];
        std::snprintf(why, sizeof why,
                      "photo %zu shows markers laid out unlike this machine's delta "
                      "target (one is %.1f mm out of place): a photo of another target",
                      frame + 1, worst);
        throw MeasureError(why);
    }
    return placement;
}

// The fit needs the whole bed: a quarter of the target missing is not a calibration. Markers the
// photo should show but does not are the print's fault, not the framing's; those kept as notes.
void check_markers_enough(const std::vector<vision::DetectedMarker>& found,
                          const MissingMarkers& missing, std::size_t target_markers,
                          const std::string& photo_name, DeltaMeasurement& out) {
    if (found.size() * 4 < target_markers * 3) {
        std::string why = photo_name + " shows " + std::to_string(found.size()) +
                          " of the target's " + std::to_string(target_markers) + " markers";
        if (!missing.unread.empty()) {
            why += ": " + std::to_string(missing.unread.size()) +
                   " in the frame could not be read (" + joined(missing.unread) +
                   "): a squashed, smeared or missing first layer there";
        }
        if (missing.outside_frame > 0 || missing.unread.empty()) {
            why += missing.unread.empty() ? ": " : "; ";
            why += "the artifact is partly out of frame";
        }
        throw MeasureError(why);
    }
    for (const auto& marker : missing.unread) {
        std::string line = photo_name;
        line += ": ";
        line += marker;
        line += " could not be read";
        out.markers_unread.push_back(std::move(line));
    }
}

// Each marker's scale on the bed: its sides in millimetres over its sides in pixels.
std::vector<double> marker_scales(const std::vector<vision::DetectedMarker>& found,
                                  const std::vector<std::vector<geometry::Point3>>& on_bed) {
    std::vector<double> mm_per_px;
    for (std::size_t i = 0; i < found.size(); ++i) {
        double mm = 0, px = 0;
        for (std::size_t k = 0; k < 4; ++k) {
            const auto& a = on_bed[i][k];
            const auto& b = on_bed[i][(k + 1) % 4];
            mm += std::hypot(b.x - a.x, b.y - a.y);
            px += std::hypot(found[i].corners[(k + 1) % 4].x - found[i].corners[k].x,
                             found[i].corners[(k + 1) % 4].y - found[i].corners[k].y);
        }
        mm_per_px.push_back(mm / px);
    }
    return mm_per_px;
}

// One ring's four corners into their sightings: at the target's top, and at the height the
// strand's width there says it stands (when it can be told).
void add_ring_corners(const vision::StrandRing& ring, int marker_id, double mm_per_px,
                      const std::string& photo_name, const geometry::CameraModel& camera,
                      const geometry::BedPlane& plane, Sightings& seen, DeltaMeasurement& out) {
    for (std::size_t k = 0; k < 4; ++k) {
        auto& corner = seen[{marker_id, static_cast<int>(k)}];
        const double top = out.target.top_height_mm;
        const auto at_top = geometry::pixels_to_bed(camera, plane, {ring.corners_px[k]}, top)[0];
        corner.at_top.push_back(at_top);
        const auto above_top =
            geometry::pixels_to_bed(camera, plane, {ring.corners_px[k]}, top + 1)[0];
        corner.shift = {above_top.x - at_top.x, above_top.y - at_top.y};
        const double sigma_mm = ring.sigma_px[k] * mm_per_px;
        corner.edge_variance_sum += sigma_mm * sigma_mm;
        if (!ring.width_unmeasured_because[k].empty()) {
            out.heights_unmeasured.push_back(photo_name + ": marker " + std::to_string(marker_id) +
                                             "'s corner " + std::to_string(k) + ": " +
                                             ring.width_unmeasured_because[k]);
            ++corner.heights_unmeasured;  // its points are then at_top's alone
            continue;
        }
        const auto height = vision::strand_height_from_width(out.target.strand_section_mm2,
                                                             ring.width_px[k] * mm_per_px,
                                                             ring.width_sigma_px[k] * mm_per_px);
        corner.on_bed.push_back(
            geometry::pixels_to_bed(camera, plane, {ring.corners_px[k]}, height.height_mm)[0]);
        corner.height_variance_sum += height.sigma_mm * height.sigma_mm;
        corner.free_beads += height.free_bead ? 1 : 0;
        corner.scraped += height.scraped ? 1 : 0;
    }
}

// One photo measured into the sightings: its markers checked against the target, then each
// marker's ring strand and its corners where its sides' centrelines meet (where the nozzle went,
// however wide the strand lies), each mapped to the bed at the height its width says.
void measure_frame(const vision::GrayView& frame, std::size_t f,
                   const vision::MarkerOptions& options, const geometry::CameraModel& camera,
                   const geometry::BedPlane& plane, Sightings& seen, DeltaMeasurement& out) {
    const auto& markers = out.target.markers;
    const std::string photo_name = "photo " + std::to_string(f + 1);
    if (const auto size = geometry::photo_size_mismatch(camera, frame.width_px, frame.height_px);
        !size.empty())
        throw MeasureError(photo_name + " is " + size);
    check_exposure(frame, f);
    auto found = target_markers_in(frame, photo_name, options, markers.size());
    const auto on_bed = corners_at_top(found, camera, plane, out.target.top_height_mm);
    const auto laid_on_bed = layout_on_bed(found, on_bed, out.target, f);
    const auto missing = laid_on_bed
                             ? missing_markers(out.target, found, *laid_on_bed, camera, plane)
                             : MissingMarkers{};
    check_markers_enough(found, missing, markers.size(), photo_name, out);
    const auto mm_per_px = marker_scales(found, on_bed);
    // Each ring is measured on its own (the photo and the camera only read), on all cores.
    std::vector<vision::StrandRing> rings(found.size());
    each_on_all_cores(found.size(), [&](std::size_t i) {
        const auto& marker = markers[static_cast<std::size_t>(found[i].id)];
        const vision::StrandRingLayout layout{out.target.marker_half_mm, marker.outline_half_mm,
                                              out.target.strand_width_mm, out.target.ring_gap_mm};
        rings[i] = vision::measure_strand_ring(frame, found[i].corners, layout, &camera);
    });
    for (std::size_t i = 0; i < found.size(); ++i) {
        if (!rings[i].measured()) {
            out.rings_unmeasured.push_back(photo_name + ": marker " + std::to_string(found[i].id) +
                                           "'s ring: " + rings[i].unmeasured_because);
            continue;
        }
        add_ring_corners(rings[i], found[i].id, mm_per_px[i], photo_name, camera, plane, seen, out);
    }
    out.frames.push_back(std::move(found));
}

// A corner's feature from every frame's sighting of it. Its uncertainty in one frame: what its
// edge fits' own scatter gives (sensor noise, a ragged strand edge), on top of a floor for what
// they cannot see (the camera's and the plane's calibration, the print's texture): on the twin's
// 12 MP photos the corners are 0.003-0.005 mm from the material while their edge fits alone
// claim 0.0004 mm. Several frames average, and their scatter is used when it is larger.
solve::FeatureMeasurement corner_feature(std::pair<int, int> key, const CornerSightings& corner,
                                         const DeltaMeasurement& out) {
    constexpr double kFrameFloorMm = 0.005;
    // A height one frame could not tell is the surface fit's in all: the frames' points are
    // averaged at one height.
    const bool height_measured = corner.heights_unmeasured == 0;
    const auto& points = height_measured ? corner.on_bed : corner.at_top;
    const auto& target_corner = out.target.markers[static_cast<std::size_t>(key.first)]
                                    .outline_corners_mm[static_cast<std::size_t>(key.second)];
    double mx = 0, my = 0, mz = 0;
    for (const auto& p : points) mx += p.x, my += p.y, mz += p.z;
    const double n = static_cast<double>(points.size());
    // As printed: the bed has grown or shrunk since, about a point the placement absorbs.
    mx /= n * out.bed_scale, my /= n * out.bed_scale;
    double scatter = 0;
    for (const auto& p : points) {
        const double dx = p.x / out.bed_scale - mx, dy = p.y / out.bed_scale - my;
        scatter += dx * dx + dy * dy;
    }
    mz /= n;
    double height_scatter = 0;
    for (const auto& p : points) height_scatter += (p.z - mz) * (p.z - mz);
    // The strand's height, its uncertainty (the frames' own, or their disagreement) and the XY
    // uncertainty it brings along the ray. A strand's width varies along a side as one over the
    // gap, which the widths' straight fit only follows closely: on the twin the heights at the
    // corners are within 0.005 mm where their fits claim a tenth of that. That floor is added in
    // quadrature.
    constexpr double kHeightFloorMm = 0.005;
    // Unmeasured, the height is the fit's, which moves the point along its ray itself.
    const double height_sigma =
        !height_measured
            ? 0.0
            : std::max(std::sqrt(corner.height_variance_sum / n + kHeightFloorMm * kHeightFloorMm),
                       n > 1 ? std::sqrt(height_scatter / (n - 1)) : 0.0) /
                  std::sqrt(n);
    const double along_ray = height_sigma * std::hypot(corner.shift.x, corner.shift.y);
    const double frame_sigma =
        std::sqrt(kFrameFloorMm * kFrameFloorMm + corner.edge_variance_sum / n);
    const double xy_sigma =
        std::max(frame_sigma, n > 1 ? std::sqrt(scatter / (2 * (n - 1))) : 0.0) / std::sqrt(n);
    solve::FeatureMeasurement feature;
    feature.id = corner_feature_id(key.first, key.second);
    feature.commanded_mm = {target_corner.x, target_corner.y, out.target.top_height_mm};
    feature.measured_mm = {mx, my};
    feature.sigma_mm = std::sqrt(xy_sigma * xy_sigma + along_ray * along_ray);
    feature.seen_at_height_mm = mz;
    feature.shift_per_height = corner.shift;
    feature.height_measured = height_measured;
    feature.height_sigma_mm = height_sigma;
    feature.free_bead = corner.free_beads * 2 > static_cast<int>(points.size());
    feature.scraped = corner.scraped * 2 > static_cast<int>(points.size());
    return feature;
}

}  // namespace

DeltaMeasurement measure_delta(const models::MachineFile& machine,
                               const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               const std::vector<vision::GrayView>& frames,
                               std::optional<double> photo_bed_temperature_c) {
    if (frames.empty()) throw MeasureError("no photos to measure");
    DeltaMeasurement out;
    try {
        out.bed_scale = models::bed_scale_at_photo(machine, photo_bed_temperature_c);
    } catch (const models::MachineFileError& e) {
        throw MeasureError(e.what());
    }
    out.target = targets::make_delta_target(machine);  // regenerated: generation is deterministic
    vision::MarkerOptions options;
    options.camera = &camera;
    look_where_the_target_stands(options, out.target, camera, plane);
    Sightings seen;
    for (std::size_t f = 0; f < frames.size(); ++f)
        measure_frame(frames[f], f, options, camera, plane, seen, out);
    for (const auto& [key, corner] : seen) out.features.push_back(corner_feature(key, corner, out));
    const SurfaceModel surface = fit_surface(machine, out);
    measure_bars(machine, camera, plane, frames, surface, out);
    return out;
}

}  // namespace calbox::modes
