#include "core/modes/delta.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <utility>

#include "core/geometry/camera_model.hpp"
#include "core/geometry/line_fit.hpp"
#include "core/models/delta.hpp"
#include "core/number_text.hpp"
#include "core/solve/placement.hpp"
#include "core/vision/edge_kernel.hpp"
#include "core/vision/strand_ring.hpp"

namespace calbox::modes {
namespace {

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
    const cv::Mat view(image.height_px, image.width_px, CV_8UC1,
                       const_cast<std::uint8_t*>(image.pixels),
                       static_cast<std::size_t>(image.stride_bytes));
    double brightest = 0;
    cv::minMaxLoc(view, nullptr, &brightest);
    if (brightest < limits.brightest_at_least_dn)
        throw MeasureError(which + " is under-exposed: nothing in it is brighter than " +
                           std::to_string(static_cast<int>(brightest)) + " of 255");
    // Bright and dark split where Otsu's method puts it: the printed lines and the bed.
    cv::Mat ignored;
    const double split = cv::threshold(view, ignored, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
    const auto total = static_cast<double>(view.total());
    const double bright = cv::countNonZero(view > split);
    const double clipped = cv::countNonZero(view >= limits.clipped_from_dn);
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
    solve::RigidPlacement placement;  // machine frame -> bed frame
    double bed_scale = 1;

    geometry::Point3 on_bed(geometry::Point3 commanded) const {
        geometry::Point3 p = commanded;
        if (truth) p = models::actual_position_mm(*truth, firmware, commanded);
        const geometry::Point2 placed = placement.apply({p.x, p.y});
        return {bed_scale * placed.x, bed_scale * placed.y, truth ? p.z : commanded.z};
    }
};

// How a bar's end face is looked for and when it is not one, with the reasons.
struct EndFaceLimits {
    // Before the printer is calibrated the face can be a millimetre or more from where the
    // target puts it: it is first looked for this far either side along the bar's centreline.
    double search_reach_mm = 3.0;
    // Then profiled closely, this far either side of where it was found: a strand's width, so
    // that no other edge (the bar's far side, a neighbouring strand) enters a profile.
    double profile_reach_mm = 0.8;
    int profiles = 15;  // across the face's flat part
    // A face with an edge in fewer profiles than this share is cut, smeared or hidden.
    double min_profile_share = 2.0 / 3.0;
    // A clean printed face is straight to a few micrometres; a blob, a gap or a stray strand
    // is not a face to measure.
    double max_face_rms_mm = 0.05;
};

// One end face of a bar in one photo: the edge points where the material stops, on the bed
// frame, found by profiles along the bar at offsets across it.
struct EndFace {
    geometry::Line line;
    double rms_mm = 0;
    std::size_t points = 0;
};

// Without a face, `why_not` says what was missing.
std::optional<EndFace> measure_end_face(const vision::GrayView& image,
                                        const geometry::CameraModel& camera,
                                        const geometry::BedPlane& plane, geometry::Point2 end,
                                        geometry::Point2 outward, double height_mm,
                                        double half_flat_mm, std::string& why_not,
                                        const EndFaceLimits& limits = {}) {
    const geometry::Point2 across{-outward.y, outward.x};
    // Material inside, bed outside: the step falls going outwards. `reach` mm either side.
    const auto edge_along = [&](geometry::Point2 centre,
                                double reach) -> std::optional<geometry::Point2> {
        const auto px = geometry::project_points(
            camera, plane.bed_to_camera,
            {{centre.x - outward.x * reach, centre.y - outward.y * reach, height_mm},
             {centre.x + outward.x * reach, centre.y + outward.y * reach, height_mm}});
        const auto edge = vision::step_edge_on_segment(image, px[0], px[1], false);
        if (!edge) return std::nullopt;
        const auto bed = geometry::pixels_to_bed(camera, plane, {*edge}, height_mm)[0];
        return geometry::Point2{bed.x, bed.y};
    };
    const auto rough = edge_along(end, limits.search_reach_mm);
    if (!rough) {
        why_not = "no edge within " + number_text("%g", limits.search_reach_mm) +
                  " mm of where it was expected";
        return std::nullopt;
    }
    std::vector<geometry::Point2> points;
    const int profiles = std::max(2, limits.profiles);
    for (int k = 0; k < profiles; ++k) {
        const double t = half_flat_mm * (2.0 * k / (profiles - 1) - 1);
        const auto p =
            edge_along({rough->x + across.x * t, rough->y + across.y * t}, limits.profile_reach_mm);
        if (p) points.push_back(*p);
    }
    if (static_cast<double>(points.size()) < limits.min_profile_share * profiles) {
        why_not = "an edge in only " + std::to_string(points.size()) + " of " +
                  std::to_string(profiles) + " profiles across it";
        return std::nullopt;
    }
    EndFace face;
    face.line = geometry::fit_line(points);
    face.rms_mm = geometry::line_rms(face.line, points);
    face.points = points.size();
    if (face.rms_mm > limits.max_face_rms_mm) {
        why_not = "not straight: its edge points lie " + number_text("%.3f", face.rms_mm) +
                  " mm RMS from a line, " + number_text("%g", limits.max_face_rms_mm) + " allowed";
        return std::nullopt;
    }
    return face;
}

// How far the face reaches along `axis` (towards `sign` * axis), the bar's centre at `centre`:
// the flat face runs `half_flat_mm` either side of the centreline before the rounded corners.
double face_reach(const EndFace& face, geometry::Point2 centre, geometry::Point2 axis,
                  double half_flat_mm, double sign) {
    const geometry::Point2 across{-axis.y, axis.x};
    const auto& l = face.line;
    const double d_across = l.direction.x * across.x + l.direction.y * across.y;
    const double p_across = (l.point.x - centre.x) * across.x + (l.point.y - centre.y) * across.y;
    double reach = -1e300;
    for (const double lateral : {-half_flat_mm, half_flat_mm}) {
        const double s = (lateral - p_across) / d_across;
        const geometry::Point2 q{l.point.x + s * l.direction.x, l.point.y + s * l.direction.y};
        reach = std::max(reach, sign * ((q.x - centre.x) * axis.x + (q.y - centre.y) * axis.y));
    }
    return sign * reach;
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
            surface.placement = solve::best_rigid_placement(commanded, measured);
        }
    }
    return surface;
}

// The classic bars, edge to edge, each end face mapped at the surface's height there.
void measure_bars(const models::MachineFile& machine, const geometry::CameraModel& camera,
                  const geometry::BedPlane& plane, const std::vector<vision::GrayView>& frames,
                  const SurfaceModel& surface, DeltaMeasurement& out) {
    const double line_width = machine.line_width_mm;
    for (const auto& bar : out.target.bars) {
        // The flat part of each end face: the bar's width less the rounded corners of its
        // perimeter line.
        const double half_flat = bar.width_mm / 2 - line_width / 2;
        const double half_profiled = bar.width_mm / 2 - line_width;
        const double top = out.target.top_height_mm;
        const auto start = surface.on_bed({bar.start_mm.x, bar.start_mm.y, top});
        const auto end = surface.on_bed({bar.end_mm.x, bar.end_mm.y, top});
        const double length_mm = std::hypot(end.x - start.x, end.y - start.y);
        const geometry::Point2 axis{(end.x - start.x) / length_mm, (end.y - start.y) / length_mm};
        std::vector<double> lengths;
        double sigma_sum = 0;
        std::array<geometry::Point3, 2> faces_seen{};
        std::string why_not;
        for (std::size_t f = 0; f < frames.size(); ++f) {
            const auto& frame = frames[f];
            std::string near_why, far_why;
            const auto near =
                measure_end_face(frame, camera, plane, {start.x, start.y}, {-axis.x, -axis.y},
                                 start.z, half_profiled, near_why);
            const auto far = measure_end_face(frame, camera, plane, {end.x, end.y}, axis, end.z,
                                              half_profiled, far_why);
            if (!near || !far) {
                why_not = std::string("bar ") + bar.tower + ": photo " + std::to_string(f + 1) +
                          ": its " + (near ? "outer" : "inner") +
                          " end face: " + (near ? far_why : near_why);
                break;
            }
            if (lengths.empty()) {
                faces_seen = {geometry::Point3{near->line.point.x, near->line.point.y, start.z},
                              geometry::Point3{far->line.point.x, far->line.point.y, end.z}};
            }
            // The bar's own axis, through the middles of its end faces.
            const geometry::Point2 a{far->line.point.x - near->line.point.x,
                                     far->line.point.y - near->line.point.y};
            const double n = std::hypot(a.x, a.y);
            const geometry::Point2 u{a.x / n, a.y / n};
            const double reach_far = face_reach(*far, near->line.point, u, half_flat, 1);
            const double reach_near = face_reach(*near, near->line.point, u, half_flat, -1);
            lengths.push_back((reach_far - reach_near) / out.bed_scale);
            // Each face's position from its points' scatter.
            sigma_sum += near->rms_mm * near->rms_mm / static_cast<double>(near->points) +
                         far->rms_mm * far->rms_mm / static_cast<double>(far->points);
        }
        if (lengths.size() != frames.size()) {  // not measurable in every photo
            out.bars_unmeasured.push_back(why_not);
            continue;
        }
        BarLengthMeasurement m;
        m.tower = bar.tower;
        m.commanded_from_mm = std::hypot(bar.start_mm.x, bar.start_mm.y);
        m.commanded_to_mm = std::hypot(bar.end_mm.x, bar.end_mm.y);
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
        m.surface_height_mm = (start.z + end.z) / 2;
        m.faces_seen_mm = faces_seen;
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
                               const solve::RigidPlacement& placement,
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
    const auto& markers = out.target.markers;
    vision::MarkerOptions options;
    options.camera = &camera;
    // Per corner, what the frames that saw it gave.
    struct CornerSightings {
        std::vector<geometry::Point3> on_bed;  // at the strand's height each frame measured
        geometry::Point2 shift;                // bed mm per mm of height along the ray
        double edge_variance_sum = 0;    // of each frame's centreline-fit uncertainty, in bed mm^2
        double height_variance_sum = 0;  // of each frame's strand height, mm^2
        int free_beads = 0;              // frames whose strand there was a free bead
        int scraped = 0;                 // frames whose strand there was scraped
    };
    std::map<std::pair<int, int>, CornerSightings> seen;
    for (std::size_t f = 0; f < frames.size(); ++f) {
        const auto& frame = frames[f];
        if (frame.width_px != camera.image_width || frame.height_px != camera.image_height) {
            throw MeasureError(
                "photo " + std::to_string(f + 1) + " is " + std::to_string(frame.width_px) + "x" +
                std::to_string(frame.height_px) + ", the camera was calibrated at " +
                std::to_string(camera.image_width) + "x" + std::to_string(camera.image_height));
        }
        check_exposure(frame, f);
        auto found = vision::detect_markers(frame, options);
        if (found.empty())
            throw MeasureError("photo " + std::to_string(f + 1) + " shows no " +
                               options.dictionary + " markers");
        const auto foreign = std::count_if(found.begin(), found.end(), [&](const auto& m) {
            return m.id >= static_cast<int>(markers.size());
        });
        if (foreign * 2 > static_cast<long>(found.size())) {
            throw MeasureError("photo " + std::to_string(f + 1) +
                               " shows markers that are not this machine's delta target");
        }
        found.erase(
            std::remove_if(found.begin(), found.end(),
                           [&](const auto& m) { return m.id >= static_cast<int>(markers.size()); }),
            found.end());
        // Each marker's corners on the bed at the target's top: for the layout and the scale.
        std::vector<std::vector<geometry::Point3>> on_bed;
        for (const auto& m : found) {
            const std::vector<geometry::Point2> corners(m.corners.begin(), m.corners.end());
            on_bed.push_back(
                geometry::pixels_to_bed(camera, plane, corners, out.target.top_height_mm));
        }
        // The markers must lie as this target lays them out, give or take what an uncalibrated
        // printer does to it: another ArUco artifact (a board, another machine's target) does not.
        std::optional<solve::RigidPlacement> laid_on_bed;
        if (found.size() >= 2) {
            std::vector<geometry::Point2> laid, seen_centres;
            for (std::size_t i = 0; i < found.size(); ++i) {
                laid.push_back(markers[static_cast<std::size_t>(found[i].id)].centre_mm);
                const auto& bed = on_bed[i];
                seen_centres.push_back({(bed[0].x + bed[1].x + bed[2].x + bed[3].x) / 4,
                                        (bed[0].y + bed[1].y + bed[2].y + bed[3].y) / 4});
            }
            const auto placement = solve::best_rigid_placement(laid, seen_centres);
            laid_on_bed = placement;
            double worst = 0;
            for (std::size_t i = 0; i < laid.size(); ++i) {
                const auto p = placement.apply(laid[i]);
                worst =
                    std::max(worst, std::hypot(p.x - seen_centres[i].x, p.y - seen_centres[i].y));
            }
            constexpr double kLayoutToleranceMm = 4.0;
            if (worst > kLayoutToleranceMm) {
                char why[200];
                std::snprintf(why, sizeof why,
                              "photo %zu shows markers laid out unlike this machine's delta "
                              "target (one is %.1f mm out of place): a photo of another target",
                              f + 1, worst);
                throw MeasureError(why);
            }
        }
        // The fit needs the whole bed: a quarter of the target missing is not a calibration.
        // Markers the photo should show but does not are the print's fault, not the framing's.
        const auto missing = laid_on_bed
                                 ? missing_markers(out.target, found, *laid_on_bed, camera, plane)
                                 : MissingMarkers{};
        const std::string photo_name = "photo " + std::to_string(f + 1);
        if (found.size() * 4 < markers.size() * 3) {
            std::string why = photo_name + " shows " + std::to_string(found.size()) +
                              " of the target's " + std::to_string(markers.size()) + " markers";
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
        // Each marker's scale on the bed: its sides in millimetres over its sides in pixels.
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
        // The features: each marker's ring strand, its corners where its sides' centrelines
        // meet (where the nozzle went, however wide the strand lies), each mapped to the bed at
        // the height the strand's width there says it stands.
        for (std::size_t i = 0; i < found.size(); ++i) {
            const auto& marker = markers[static_cast<std::size_t>(found[i].id)];
            const vision::StrandRingLayout layout{out.target.marker_half_mm, marker.outline_half_mm,
                                                  out.target.strand_width_mm,
                                                  out.target.ring_gap_mm};
            const auto ring = vision::measure_strand_ring(frame, found[i].corners, layout, &camera);
            if (!ring.measured()) {
                out.rings_unmeasured.push_back(photo_name + ": marker " +
                                               std::to_string(found[i].id) +
                                               "'s ring: " + ring.unmeasured_because);
                continue;
            }
            for (std::size_t k = 0; k < 4; ++k) {
                const auto height = vision::strand_height_from_width(
                    out.target.strand_section_mm2, ring.width_px[k] * mm_per_px[i],
                    ring.width_sigma_px[k] * mm_per_px[i]);
                const auto at = geometry::pixels_to_bed(camera, plane, {ring.corners_px[k]},
                                                        height.height_mm)[0];
                const auto above = geometry::pixels_to_bed(camera, plane, {ring.corners_px[k]},
                                                           height.height_mm + 1)[0];
                auto& corner = seen[{found[i].id, static_cast<int>(k)}];
                corner.on_bed.push_back(at);
                const double sigma_mm = ring.sigma_px[k] * mm_per_px[i];
                corner.edge_variance_sum += sigma_mm * sigma_mm;
                corner.height_variance_sum += height.sigma_mm * height.sigma_mm;
                corner.free_beads += height.free_bead ? 1 : 0;
                corner.scraped += height.scraped ? 1 : 0;
                corner.shift = {above.x - at.x, above.y - at.y};
            }
        }
        out.frames.push_back(std::move(found));
    }
    // A corner's uncertainty in one frame: what its edge fits' own scatter gives (sensor noise,
    // a ragged strand edge), on top of a floor for what they cannot see (the camera's and the
    // plane's calibration, the print's texture): on the twin's 12 MP photos the corners are
    // 0.003-0.005 mm from the material while their edge fits alone claim 0.0004 mm. Several
    // frames average, and their scatter is used when it is larger.
    constexpr double kFrameFloorMm = 0.005;
    for (const auto& [key, corner] : seen) {
        const auto& points = corner.on_bed;
        const auto& target_corner = markers[static_cast<std::size_t>(key.first)]
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
        // The strand's height, its uncertainty (the frames' own, or their disagreement) and the
        // XY uncertainty it brings along the ray.
        // A strand's width varies along a side as one over the gap, which the widths' straight
        // fit only follows closely: on the twin the heights at the corners are within 0.005 mm
        // where their fits claim a tenth of that. That floor is added in quadrature.
        constexpr double kHeightFloorMm = 0.005;
        const double height_sigma =
            std::max(std::sqrt(corner.height_variance_sum / n + kHeightFloorMm * kHeightFloorMm),
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
        feature.height_measured = true;
        feature.height_sigma_mm = height_sigma;
        feature.free_bead = corner.free_beads * 2 > static_cast<int>(points.size());
        feature.scraped = corner.scraped * 2 > static_cast<int>(points.size());
        out.features.push_back(feature);
    }
    const SurfaceModel surface = fit_surface(machine, out);
    measure_bars(machine, camera, plane, frames, surface, out);
    return out;
}

}  // namespace calbox::modes
