#include "core/modes/bed_view.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "core/number_text.hpp"

namespace calbox::modes {

using geometry::Point2;
using geometry::Point3;

namespace {

Point2 turned(Point2 p, double angle_rad) {
    const double c = std::cos(angle_rad), s = std::sin(angle_rad);
    return {c * p.x - s * p.y, s * p.x + c * p.y};
}

std::string three_decimals(double v) {
    return number_text("%.3f", v);
}

// The view never shows more than this: a 300 x 300 mm bed at 0.05 mm a pixel.
constexpr double kMaxViewPixels = 40e6;

}  // namespace

Point2 BedToMachine::machine_of(Point2 bed_mm) const {
    const Point2 m = mirrored ? Point2{bed_mm.x, -bed_mm.y} : bed_mm;
    const Point2 r = turned(m, rotation_rad);
    return {r.x + translation_mm.x, r.y + translation_mm.y};
}

Point2 BedToMachine::bed_of(Point2 machine_mm) const {
    const Point2 m =
        turned({machine_mm.x - translation_mm.x, machine_mm.y - translation_mm.y}, -rotation_rad);
    return mirrored ? Point2{m.x, -m.y} : m;
}

BedToMachine planar_bed_to_machine(const PlanarSolution& solution, const std::string& source) {
    if (!solution.frame)
        throw BedViewError(source +
                           ": a result from before calbox recorded the frame it was measured in "
                           "(work zero, travel): solve the measurements again");
    if (!solution.bed_mirrored)
        throw BedViewError(source +
                           ": a result from before calbox recorded which way round the camera's "
                           "bed lies: solve the measurements again");
    // The solve saw each hole at R (c + e(c)) + t in the (unmirrored) bed frame; a job aimed at p
    // through the correction lands where c + e(c) = Rr p + o (the rigid part left out): so
    // p = Rr^-1 (R^-1 (m - t) - o), and the machine's coordinates add the work zero.
    const double theta = solution.fit.rotation_rad, phi = solution.rigid_part.rotation_rad;
    const Point2 unturned =
        turned({-solution.fit.translation_mm.x, -solution.fit.translation_mm.y}, -theta);
    const Point2 shift = turned({unturned.x - solution.rigid_part.offset_mm.x,
                                 unturned.y - solution.rigid_part.offset_mm.y},
                                -phi);
    BedToMachine map;
    map.mirrored = *solution.bed_mirrored;
    map.rotation_rad = -(theta + phi);
    map.translation_mm = {shift.x + solution.frame->work_zero_mm.x,
                          shift.y + solution.frame->work_zero_mm.y};
    return map;
}

BedToMachine photo_on_machine(const geometry::CameraModel& camera, const vision::GrayView& photo,
                              const PlanarSolution& solution, const std::string& source) {
    photo.check();
    if (const auto mismatch =
            geometry::photo_size_mismatch(camera, photo.width_px, photo.height_px);
        !mismatch.empty())
        throw BedViewError("the photo is " + mismatch);
    return planar_bed_to_machine(solution, source);
}

double photo_px_per_mm(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                       const Point3& at, const Point3& x_step, const Point3& y_step) {
    const auto px = geometry::project_points(camera, plane.bed_to_camera, {at, x_step, y_step});
    return 0.5 * (std::hypot(px[1].x - px[0].x, px[1].y - px[0].y) +
                  std::hypot(px[2].x - px[0].x, px[2].y - px[0].y));
}

Point2 BedView::machine_of_pixel(double column, double row) const {
    return {min_x_mm + (column + 0.5) * mm_per_px, max_y_mm - (row + 0.5) * mm_per_px};
}

Point2 BedView::pixel_of_machine(Point2 machine_mm) const {
    return {(machine_mm.x - min_x_mm) / mm_per_px - 0.5,
            (max_y_mm - machine_mm.y) / mm_per_px - 0.5};
}

namespace {

// The view's area: the request's, or the whole travel where it gives none; refused where it has no
// size or leaves the travel. Its text names it in refusals.
std::string view_area(BedView& view, const BedViewRequest& request, const PlanarFrame& f) {
    const bool whole_travel = request.min_x_mm == 0 && request.min_y_mm == 0 &&
                              request.max_x_mm == 0 && request.max_y_mm == 0;
    view.min_x_mm = whole_travel ? f.travel_min_x_mm : request.min_x_mm;
    view.min_y_mm = whole_travel ? f.travel_min_y_mm : request.min_y_mm;
    view.max_x_mm = whole_travel ? f.travel_max_x_mm : request.max_x_mm;
    view.max_y_mm = whole_travel ? f.travel_max_y_mm : request.max_y_mm;
    const std::string area = "X " + three_decimals(view.min_x_mm) + ".." +
                             three_decimals(view.max_x_mm) + " Y " + three_decimals(view.min_y_mm) +
                             ".." + three_decimals(view.max_y_mm) + " mm";
    if (!(view.max_x_mm > view.min_x_mm && view.max_y_mm > view.min_y_mm))
        throw BedViewError("the area " + area + " has no size");
    constexpr double kEdgeMm = 1e-6;
    if (view.min_x_mm < f.travel_min_x_mm - kEdgeMm ||
        view.max_x_mm > f.travel_max_x_mm + kEdgeMm ||
        view.min_y_mm < f.travel_min_y_mm - kEdgeMm || view.max_y_mm > f.travel_max_y_mm + kEdgeMm)
        throw BedViewError(
            "the area " + area + " reaches beyond the machine's travel (X " +
            three_decimals(f.travel_min_x_mm) + ".." + three_decimals(f.travel_max_x_mm) + " Y " +
            three_decimals(f.travel_min_y_mm) + ".." + three_decimals(f.travel_max_y_mm) + " mm)");
    return area;
}

// Where the lens's polynomial holds: a ray it was never fitted to can fold back into the photo,
// so a sample counts only when it is in front of the camera, within the photo's widest ray, and
// lands in the photo.
struct LensReach {
    cv::Matx33d rotation;
    cv::Vec3d shift;
    double widest_ray = 0;
    double width_px = 0, height_px = 0;

    bool within_lens(const Point3& p) const {
        const cv::Vec3d c = rotation * cv::Vec3d(p.x, p.y, p.z) + shift;
        return c[2] > 0 && std::hypot(c[0], c[1]) <= widest_ray * c[2];
    }
    bool in_photo(Point2 p) const {
        return p.x >= 0 && p.y >= 0 && p.x <= width_px - 1 && p.y <= height_px - 1;
    }
};

LensReach lens_reach(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                     const vision::GrayView& photo) {
    LensReach reach;
    reach.width_px = photo.width_px;
    reach.height_px = photo.height_px;
    cv::Rodrigues(cv::Vec3d(plane.bed_to_camera.rvec[0], plane.bed_to_camera.rvec[1],
                            plane.bed_to_camera.rvec[2]),
                  reach.rotation);
    reach.shift = cv::Vec3d(plane.bed_to_camera.tvec_mm[0], plane.bed_to_camera.tvec_mm[1],
                            plane.bed_to_camera.tvec_mm[2]);
    const double w = photo.width_px - 1, hgt = photo.height_px - 1;
    for (const Point2& n : geometry::undistort_to_normalized(camera, {{0, 0},
                                                                      {w / 2, 0},
                                                                      {w, 0},
                                                                      {w, hgt / 2},
                                                                      {w, hgt},
                                                                      {w / 2, hgt},
                                                                      {0, hgt},
                                                                      {0, hgt / 2}}))
        reach.widest_ray = std::max(reach.widest_ray, std::hypot(n.x, n.y));
    return reach;
}

// A machine point on the surface the view shows, in the bed's frame.
struct BedAt {
    const BedToMachine& map;
    double height_mm;
    Point3 operator()(Point2 machine) const {
        const Point2 b = map.bed_of(machine);
        return Point3{b.x, b.y, height_mm};
    }
};

// The point of the area nearest its middle that the photo shows, where the photo's own scale is
// taken (a lens's polynomial says nothing of rays outside the photo), or none.
std::optional<Point2> nearest_seen(const BedView& view, const geometry::CameraModel& camera,
                                   const geometry::BedPlane& plane, const LensReach& reach,
                                   const BedAt& bed_point) {
    constexpr int kProbes = 21;
    const Point2 middle{0.5 * (view.min_x_mm + view.max_x_mm),
                        0.5 * (view.min_y_mm + view.max_y_mm)};
    std::vector<Point2> probes;
    std::vector<Point3> probe_points;
    for (int j = 0; j < kProbes; ++j)
        for (int i = 0; i < kProbes; ++i) {
            const Point2 p{view.min_x_mm + (view.max_x_mm - view.min_x_mm) * i / (kProbes - 1),
                           view.min_y_mm + (view.max_y_mm - view.min_y_mm) * j / (kProbes - 1)};
            probes.push_back(p);
            probe_points.push_back(bed_point(p));
        }
    const auto probed = geometry::project_points(camera, plane.bed_to_camera, probe_points);
    std::optional<Point2> nearest;
    for (std::size_t k = 0; k < probes.size(); ++k)
        if (reach.in_photo(probed[k]) && reach.within_lens(probe_points[k]) &&
            (!nearest || std::hypot(probes[k].x - middle.x, probes[k].y - middle.y) <
                             std::hypot(nearest->x - middle.x, nearest->y - middle.y)))
            nearest = probes[k];
    return nearest;
}

// The view's scale (the request's, or the photo's own rounded up to 0.01 mm) and its whole
// pixels from the area's top-left corner, none past the area: the far edges move in by under a
// pixel. Refused finer than a tenth of the photo's or over 40 megapixels.
cv::Size view_pixels(BedView& view, const BedViewRequest& request, const std::string& area) {
    view.mm_per_px = request.mm_per_px > 0 ? request.mm_per_px
                                           : std::ceil(view.camera_mm_per_px * 100 - 1e-9) / 100;
    if (view.mm_per_px < 0.1 * view.camera_mm_per_px)
        throw BedViewError(
            three_decimals(view.mm_per_px) + " mm a pixel is under a tenth of the photo's own " +
            three_decimals(view.camera_mm_per_px) + " mm there: nothing finer can be seen");
    const double columns_exact = (view.max_x_mm - view.min_x_mm) / view.mm_per_px;
    const double rows_exact = (view.max_y_mm - view.min_y_mm) / view.mm_per_px;
    if (columns_exact * rows_exact > kMaxViewPixels)
        throw BedViewError(area + " at " + three_decimals(view.mm_per_px) +
                           " mm a pixel would be " + number_text("%.0f", columns_exact) + " x " +
                           number_text("%.0f", rows_exact) +
                           " pixels, over 40 megapixels: give a coarser scale");
    // Whole pixels from the area's top-left corner, none past the area (nor the travel): the far
    // edges move in by under a pixel.
    const int columns = std::max(1, static_cast<int>(std::floor(columns_exact + 1e-9)));
    const int rows = std::max(1, static_cast<int>(std::floor(rows_exact + 1e-9)));
    view.max_x_mm = view.min_x_mm + columns * view.mm_per_px;
    view.min_y_mm = view.max_y_mm - rows * view.mm_per_px;

    return {columns, rows};
}

// The lens and the perspective change slowly across the bed: the photo's coordinates are
// projected at every eighth sample each way and interpolated between (bilinearly: a thousandth of
// a pixel off the projection there), a sample counting as seen where it lands in the photo and
// its four nodes all lie within the lens's widest ray.
constexpr int kNodeStep = 8;

std::vector<int> sample_nodes(int samples) {
    std::vector<int> nodes;
    for (int i = 0; i < samples; i += kNodeStep) nodes.push_back(i);
    if (nodes.back() != samples - 1) nodes.push_back(samples - 1);
    return nodes;
}

// The view drawn a band of rows at a time: the photo's coordinates of every sample in the band,
// then OpenCV's bilinear remap; each view pixel averages `k` x `k` samples.
struct BandSampler {
    const geometry::CameraModel& camera;
    const geometry::BedPlane& plane;
    const LensReach& reach;
    const BedAt& bed_point;
    const cv::Mat& source;
    const BedView& view;
    int k = 1;
    double step = 0;
    int sample_cols = 0;
    std::vector<int> node_cols;

    void draw(int top, int band, cv::Mat& out, cv::Mat& seen_mask) const {
        const int sample_rows = band * k;
        const std::vector<int> node_rows = sample_nodes(sample_rows);
        std::vector<Point3> nodes;
        nodes.reserve(node_rows.size() * node_cols.size());
        for (const int r : node_rows) {
            const double y = view.max_y_mm - (top * k + r + 0.5) * step;
            for (const int c : node_cols)
                nodes.push_back(bed_point({view.min_x_mm + (c + 0.5) * step, y}));
        }
        const auto node_px = geometry::project_points(camera, plane.bed_to_camera, nodes);
        std::vector<char> node_ok(nodes.size());
        for (std::size_t n = 0; n < nodes.size(); ++n)
            node_ok[n] = reach.within_lens(nodes[n]) ? 1 : 0;
        const std::size_t stride = node_cols.size();
        cv::Mat map_x(sample_rows, sample_cols, CV_32FC1),
            map_y(sample_rows, sample_cols, CV_32FC1);
        cv::Mat inside(sample_rows, sample_cols, CV_8UC1);
        std::size_t nr = 0;
        for (int r = 0; r < sample_rows; ++r) {
            while (nr + 2 < node_rows.size() && r > node_rows[nr + 1]) ++nr;
            const std::size_t nr1 = std::min(nr + 1, node_rows.size() - 1);
            const double fr = nr1 == nr ? 0.0
                                        : static_cast<double>(r - node_rows[nr]) /
                                              (node_rows[nr1] - node_rows[nr]);
            auto* mx = map_x.ptr<float>(r);
            auto* my = map_y.ptr<float>(r);
            auto* in = inside.ptr<std::uint8_t>(r);
            std::size_t nc = 0;
            for (int c = 0; c < sample_cols; ++c) {
                while (nc + 2 < node_cols.size() && c > node_cols[nc + 1]) ++nc;
                const std::size_t nc1 = std::min(nc + 1, node_cols.size() - 1);
                const double fc = nc1 == nc ? 0.0
                                            : static_cast<double>(c - node_cols[nc]) /
                                                  (node_cols[nc1] - node_cols[nc]);
                const std::size_t a = nr * stride + nc, b = nr * stride + nc1,
                                  d = nr1 * stride + nc, e = nr1 * stride + nc1;
                const Point2 p{(1 - fr) * ((1 - fc) * node_px[a].x + fc * node_px[b].x) +
                                   fr * ((1 - fc) * node_px[d].x + fc * node_px[e].x),
                               (1 - fr) * ((1 - fc) * node_px[a].y + fc * node_px[b].y) +
                                   fr * ((1 - fc) * node_px[d].y + fc * node_px[e].y)};
                const bool ok =
                    reach.in_photo(p) && node_ok[a] && node_ok[b] && node_ok[d] && node_ok[e];
                in[c] = ok ? 255 : 0;
                mx[c] = ok ? static_cast<float>(p.x) : -1.0F;
                my[c] = ok ? static_cast<float>(p.y) : -1.0F;
            }
        }
        cv::Mat sampled;
        cv::remap(source, sampled, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
        cv::Mat target = out.rowRange(top, top + band);
        cv::Mat seen_band = seen_mask.rowRange(top, top + band);
        if (k == 1) {
            sampled.copyTo(target);
            inside.copyTo(seen_band);
        } else {
            cv::resize(sampled, target, target.size(), 0, 0, cv::INTER_AREA);
            cv::Mat covered;
            cv::resize(inside, covered, target.size(), 0, 0, cv::INTER_AREA);
            // A view pixel counts as seen when most of its samples are.
            cv::threshold(covered, seen_band, 127, 255, cv::THRESH_BINARY);
        }
    }
};

}  // namespace

BedView render_bed_view(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                        const vision::GrayView& photo, const PlanarSolution& solution,
                        const BedViewRequest& request, const std::string& source) {
    const BedToMachine map = photo_on_machine(camera, photo, solution, source);
    BedView view;
    const std::string area = view_area(view, request, *solution.frame);
    if (!(request.surface_height_mm >= 0 && request.surface_height_mm < 500))
        throw BedViewError("a surface " + three_decimals(request.surface_height_mm) +
                           " mm above the bed: give 0 to 500 mm");
    view.surface_height_mm = request.surface_height_mm;

    const BedAt bed_point{map, request.surface_height_mm};
    const LensReach reach = lens_reach(camera, plane, photo);
    const std::optional<Point2> nearest = nearest_seen(view, camera, plane, reach, bed_point);
    if (!nearest)
        throw BedViewError("the camera sees none of " + area + " at " +
                           three_decimals(request.surface_height_mm) + " mm above the bed");
    view.camera_mm_per_px = 1 / photo_px_per_mm(camera, plane, bed_point(*nearest),
                                                bed_point({nearest->x + 1, nearest->y}),
                                                bed_point({nearest->x, nearest->y + 1}));
    const cv::Size size = view_pixels(view, request, area);
    const int columns = size.width, rows = size.height;

    // Each view pixel averages `k` x `k` samples where it is coarser than the photo, so that the
    // photo's detail does not alias into it.
    const int k =
        request.average_samples
            ? std::clamp(
                  static_cast<int>(std::ceil(view.mm_per_px / (1.25 * view.camera_mm_per_px))), 1,
                  8)
            : 1;
    const cv::Mat source_image(photo.height_px, photo.width_px, CV_8UC1,
                               const_cast<std::uint8_t*>(photo.pixels),
                               static_cast<std::size_t>(photo.stride_bytes));
    cv::Mat out(rows, columns, CV_8UC1), seen_mask(rows, columns, CV_8UC1);
    constexpr int kBandRows = 32;
    BandSampler sampler{camera,
                        plane,
                        reach,
                        bed_point,
                        source_image,
                        view,
                        k,
                        view.mm_per_px / k,
                        columns * k,
                        sample_nodes(columns * k)};
    for (int top = 0; top < rows; top += kBandRows)
        sampler.draw(top, std::min(kBandRows, rows - top), out, seen_mask);
    const long seen = cv::countNonZero(seen_mask);
    view.seen_share = static_cast<double>(seen) / (static_cast<double>(rows) * columns);
    if (seen == 0)
        throw BedViewError("the camera sees none of " + area + " at " +
                           three_decimals(request.surface_height_mm) + " mm above the bed");
    view.pixels.width_px = columns;
    view.pixels.height_px = rows;
    view.pixels.pixels.assign(out.data, out.data + static_cast<std::size_t>(rows) * columns);
    view.seen.width_px = columns;
    view.seen.height_px = rows;
    view.seen.pixels.assign(seen_mask.data,
                            seen_mask.data + static_cast<std::size_t>(rows) * columns);
    const double camera_mm = view.camera_mm_per_px * camera.rms_px;
    const double plane_mm = view.camera_mm_per_px * plane.rms_px;
    view.accuracy_mm = 2 * std::sqrt(camera_mm * camera_mm + plane_mm * plane_mm +
                                     solution.fit.residual_rms_mm * solution.fit.residual_rms_mm);
    return view;
}

std::vector<std::uint8_t> bed_view_with_overlay(const BedView& view,
                                                const PlanarSolution& solution) {
    cv::Mat gray(view.pixels.height_px, view.pixels.width_px, CV_8UC1,
                 const_cast<std::uint8_t*>(view.pixels.pixels.data()));
    cv::Mat colour;
    cv::cvtColor(gray, colour, cv::COLOR_GRAY2BGR);
    constexpr int kShift = 4;  // sub-pixel drawing
    const auto at = [&](Point2 machine) {
        const Point2 p = view.pixel_of_machine(machine);
        return cv::Point(static_cast<int>(std::lround((p.x + 0.5) * (1 << kShift))),
                         static_cast<int>(std::lround((p.y + 0.5) * (1 << kShift))));
    };
    const int thickness = std::max(1, static_cast<int>(std::lround(view.pixels.width_px / 800.0)));
    const auto rectangle = [&](double x0, double y0, double x1, double y1,
                               const cv::Scalar& colour_bgr) {
        const cv::Point a = at({x0, y0}), b = at({x1, y0}), c = at({x1, y1}), d = at({x0, y1});
        for (const auto& [from, to] : {std::pair{a, b}, {b, c}, {c, d}, {d, a}})
            cv::line(colour, from, to, colour_bgr, thickness, cv::LINE_AA, kShift);
    };
    if (solution.frame) {
        const auto& f = *solution.frame;
        rectangle(f.travel_min_x_mm, f.travel_min_y_mm, f.travel_max_x_mm, f.travel_max_y_mm,
                  cv::Scalar(230, 120, 0));
        const Point2 zero = f.work_zero_mm;
        rectangle(solution.min_x_mm + zero.x, solution.min_y_mm + zero.y,
                  solution.max_x_mm + zero.x, solution.max_y_mm + zero.y, cv::Scalar(40, 190, 40));
        // The machine's axes, a tenth of the view long, as near its zero as they fit a margin in
        // (a circle marks the zero itself where it shows), each pointing its axis's + way.
        const double length_mm =
            0.1 * std::max(view.max_x_mm - view.min_x_mm, view.max_y_mm - view.min_y_mm);
        const double margin_mm = 0.3 * length_mm;
        const auto nearest = [&](double lo, double hi) {
            return std::clamp(0.0, lo + margin_mm,
                              std::max(lo + margin_mm, hi - margin_mm - length_mm));
        };
        const Point2 anchor{nearest(view.min_x_mm, view.max_x_mm),
                            nearest(view.min_y_mm, view.max_y_mm)};
        const double x0 = anchor.x, y0 = anchor.y;
        const cv::Scalar red(30, 30, 230);
        const cv::Point x_tip = at({x0 + length_mm, anchor.y}),
                        y_tip = at({anchor.x, y0 + length_mm});
        cv::arrowedLine(colour, at({x0, anchor.y}), x_tip, red, thickness + 1, cv::LINE_AA, kShift,
                        0.15);
        cv::arrowedLine(colour, at({anchor.x, y0}), y_tip, red, thickness + 1, cv::LINE_AA, kShift,
                        0.15);
        if (0 >= view.min_x_mm && 0 <= view.max_x_mm && 0 >= view.min_y_mm && 0 <= view.max_y_mm)
            cv::circle(colour, at({0, 0}), 8 * thickness * (1 << kShift), red, thickness + 1,
                       cv::LINE_AA, kShift);
        const double font = std::max(0.5, view.pixels.width_px / 1500.0);
        const int em = static_cast<int>(std::lround(24 * font));
        cv::putText(colour, "X", cv::Point(x_tip.x >> kShift, (x_tip.y >> kShift) + em),
                    cv::FONT_HERSHEY_SIMPLEX, font, red, thickness + 1, cv::LINE_AA);
        cv::putText(colour, "Y", cv::Point((y_tip.x >> kShift) + em / 2, y_tip.y >> kShift),
                    cv::FONT_HERSHEY_SIMPLEX, font, red, thickness + 1, cv::LINE_AA);
    }
    const std::string caption = three_decimals(view.mm_per_px) + " mm/px, " +
                                three_decimals(view.surface_height_mm) + " mm above the bed, +/-" +
                                three_decimals(view.accuracy_mm) +
                                " mm (2 sigma); blue travel, green measured area";
    // The caption's size for a wide view, smaller where the view is narrower than the line.
    double font = std::max(0.4, view.pixels.width_px / 2400.0);
    int baseline = 0;
    cv::Size size = cv::getTextSize(caption, cv::FONT_HERSHEY_SIMPLEX, font, thickness, &baseline);
    if (size.width > colour.cols - 24) {
        font *= static_cast<double>(colour.cols - 24) / size.width;
        size = cv::getTextSize(caption, cv::FONT_HERSHEY_SIMPLEX, font, thickness, &baseline);
    }
    const cv::Point corner(8, colour.rows - 8 - baseline);
    cv::rectangle(colour, corner + cv::Point(-4, baseline + 4),
                  corner + cv::Point(size.width + 4, -size.height - 4), cv::Scalar(255, 255, 255),
                  cv::FILLED);
    cv::putText(colour, caption, corner, cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(0, 0, 0),
                thickness, cv::LINE_AA);
    return {colour.data, colour.data + colour.total() * colour.elemSize()};
}

std::string world_file_text(const BedView& view) {
    const Point2 first = view.machine_of_pixel(0, 0);
    const auto line = [](double v) { return number_text("%.10g", v) + "\n"; };
    return line(view.mm_per_px) + line(0) + line(0) + line(-view.mm_per_px) + line(first.x) +
           line(first.y);
}

}  // namespace calbox::modes
