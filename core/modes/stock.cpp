#include "core/modes/stock.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <vector>

#include "core/geometry/line_fit.hpp"
#include "core/median.hpp"
#include "core/modes/bed_view.hpp"
#include "core/modes/json_file.hpp"
#include "core/number_text.hpp"
#include "core/vision/edge_kernel.hpp"

namespace calbox::modes {

using geometry::Point2;
using geometry::Point3;

namespace {

constexpr const char* kCornerNames[4] = {"front-left", "front-right", "back-right", "back-left"};
constexpr const char* kEdgeNames[4] = {"front", "right", "back", "left"};

std::string at_text(Point2 p) {
    return "X" + number_text("%.1f", p.x) + " Y" + number_text("%.1f", p.y);
}

struct RoughSheet {
    std::array<Point2, 4> corners;  // machine mm, counter-clockwise from the front edge's start
    bool lighter = true;
};

// A step worth a band: a tenth of the view's spread of tones, at least a few counts of noise.
double band_step(const cv::Mat& image, const cv::Mat& seen) {
    std::vector<double> tones;
    for (int y = 0; y < image.rows; y += 4)
        for (int x = 0; x < image.cols; x += 4)
            if (seen.at<std::uint8_t>(y, x) != 0) tones.push_back(image.at<std::uint8_t>(y, x));
    std::sort(tones.begin(), tones.end());
    const double spread =
        tones.empty() ? 0 : tones[tones.size() * 95 / 100] - tones[tones.size() / 20];
    return std::max(6.0, 0.1 * spread);
}

// The view's tone at a machine point, or -1 where the camera does not see it.
struct ToneAt {
    const BedView& view;
    const cv::Mat& image;
    const cv::Mat& seen;
    double operator()(Point2 machine) const {
        const Point2 p = view.pixel_of_machine(machine);
        const int x = static_cast<int>(std::lround(p.x)), y = static_cast<int>(std::lround(p.y));
        if (x < 0 || y < 0 || x >= image.cols || y >= image.rows ||
            seen.at<std::uint8_t>(y, x) == 0)
            return -1.0;
        return static_cast<double>(image.at<std::uint8_t>(y, x));
    }
};

// The step across the sides, inside less outside, 1.5 mm either side of each.
std::vector<double> steps_across_sides(const RoughSheet& sheet, const ToneAt& tone_at,
                                       double mm_per_px) {
    std::vector<double> steps;
    for (int k = 0; k < 4; ++k) {
        const Point2 a = sheet.corners[k], b = sheet.corners[(k + 1) % 4];
        const double length = std::hypot(b.x - a.x, b.y - a.y);
        const Point2 d{(b.x - a.x) / length, (b.y - a.y) / length};
        const Point2 out{d.y, -d.x};
        const int samples = static_cast<int>(0.7 * length / (2 * mm_per_px));
        for (int i = 0; i <= samples; ++i) {
            const double t = 0.15 * length + i * 2 * mm_per_px;
            const Point2 p{a.x + t * d.x, a.y + t * d.y};
            const double in = tone_at({p.x - 1.5 * out.x, p.y - 1.5 * out.y});
            const double beyond = tone_at({p.x + 1.5 * out.x, p.y + 1.5 * out.y});
            if (in >= 0 && beyond >= 0) steps.push_back(in - beyond);
        }
    }
    return steps;
}

// The corners turned to start at the edge running nearest +X.
void front_edge_first(std::array<Point2, 4>& c) {
    int front = 0;
    double best_cos = -2;
    for (int k = 0; k < 4; ++k) {
        const Point2 d{c[(k + 1) % 4].x - c[k].x, c[(k + 1) % 4].y - c[k].y};
        const double cos_x = d.x / std::hypot(d.x, d.y);
        if (cos_x > best_cos) best_cos = cos_x, front = k;
    }
    std::rotate(c.begin(), c.begin() + front, c.end());
}

// The sheet's outline on a view coarse enough to be quick and fine enough to place each edge
// within the search. Where the view steps up or down against its own surroundings (the mean over
// a block half again the search across) marks a band along each side of every edge, whatever
// the lamp's glare or a falling light adds smoothly across the bed; every four-sided outline of
// those bands is a candidate, and the sheet is the one whose sides show the strongest step of
// one sign across them (a band's outline half a block off the sheet's edge has bed on both
// sides).
RoughSheet rough_sheet(const BedView& view, const std::string& area) {
    const cv::Mat image(view.pixels.height_px, view.pixels.width_px, CV_8UC1,
                        const_cast<std::uint8_t*>(view.pixels.pixels.data()));
    const cv::Mat seen(view.seen.height_px, view.seen.width_px, CV_8UC1,
                       const_cast<std::uint8_t*>(view.seen.pixels.data()));
    cv::Mat filled = image.clone();
    filled.setTo(cv::mean(image, seen), ~seen);
    cv::GaussianBlur(filled, filled, {0, 0}, 1.0);
    const double step = band_step(image, seen);
    const int block = 2 * static_cast<int>(std::lround(7.5 / view.mm_per_px)) + 1;
    cv::Mat unseen_or_edge = ~seen;
    cv::rectangle(unseen_or_edge, {0, 0}, {unseen_or_edge.cols - 1, unseen_or_edge.rows - 1}, 255,
                  1);
    const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, {3, 3});
    cv::dilate(unseen_or_edge, unseen_or_edge, kernel, {-1, -1}, 2);
    const ToneAt tone_at{view, image, seen};
    std::optional<RoughSheet> best;
    double best_score = 0;
    std::string why = "no outline with four straight sides";
    for (const bool lighter : {true, false}) {
        cv::Mat band;
        cv::adaptiveThreshold(filled, band, 255, cv::ADAPTIVE_THRESH_MEAN_C,
                              lighter ? cv::THRESH_BINARY : cv::THRESH_BINARY_INV, block,
                              lighter ? -step : step);
        band &= seen;
        cv::morphologyEx(band, band, cv::MORPH_OPEN, kernel);
        cv::morphologyEx(band, band, cv::MORPH_CLOSE, kernel, {-1, -1}, 2);
        std::vector<std::vector<cv::Point>> contours;
        std::vector<cv::Vec4i> hierarchy;
        cv::findContours(band, contours, hierarchy, cv::RETR_CCOMP, cv::CHAIN_APPROX_NONE);
        for (const auto& contour : contours) {
            if (cv::contourArea(contour) < 0.005 * static_cast<double>(image.total())) continue;
            std::vector<cv::Point> polygon;
            cv::approxPolyDP(contour, polygon, 0.02 * cv::arcLength(contour, true), true);
            if (polygon.size() != 4 || !cv::isContourConvex(polygon)) continue;
            bool cut = false;
            for (const auto& p : contour) cut = cut || unseen_or_edge.at<std::uint8_t>(p) != 0;
            if (cut) {
                why = "an outline runs on beyond what the camera sees";
                continue;
            }
            RoughSheet sheet;
            for (int k = 0; k < 4; ++k)
                sheet.corners[k] = view.machine_of_pixel(polygon[k].x, polygon[k].y);
            // Counter-clockwise in the machine's frame (the view's rows run down, so a contour's
            // order there is the other way round): the inside lies to the left of each side.
            double signed_area = 0;
            for (int k = 0; k < 4; ++k)
                signed_area += sheet.corners[k].x * sheet.corners[(k + 1) % 4].y -
                               sheet.corners[(k + 1) % 4].x * sheet.corners[k].y;
            if (signed_area < 0) std::reverse(sheet.corners.begin(), sheet.corners.end());
            const std::vector<double> steps = steps_across_sides(sheet, tone_at, view.mm_per_px);
            if (steps.size() < 8) continue;
            const double score = (lighter ? 1 : -1) * median_of(steps);
            if (score > best_score) {
                sheet.lighter = lighter;
                best = sheet;
                best_score = score;
            }
        }
    }
    if (!best) throw StockError("no sheet with four straight edges in " + area + ": " + why);
    front_edge_first(best->corners);
    return *best;
}

// An edge whose profile the sensor clipped (the lamp's glare on the sheet) is moved by the
// clipping: whether the photo reaches the clipped level near edge `e` along its search.
bool clipped_near(const vision::GrayView& photo, Point2 e, Point2 from, Point2 to,
                  const StockSettings& settings) {
    const Point2 along{to.x - from.x, to.y - from.y};
    const double px = std::hypot(along.x, along.y);
    bool clipped = false;
    const int reach = static_cast<int>(std::ceil(2 * settings.clip_reach_px));
    for (int i = -reach; i <= reach; ++i) {
        const double u = 0.5 * i;
        const double x = e.x + u * along.x / px, y = e.y + u * along.y / px;
        if (x >= 0 && y >= 0 && x <= photo.width_px - 2 && y <= photo.height_px - 2 &&
            vision::sample_reference(photo, x, y) >= settings.clipped_level)
            clipped = true;
    }
    return clipped;
}

// What lies off the edge's line is something else on it: set aside by the median distance's
// spread, then against the fixed limit.
std::vector<Point2> on_the_line(std::vector<Point2> points, const StockSettings& settings) {
    for (int pass = 0; pass < 4 && points.size() >= 3; ++pass) {
        const auto line = geometry::fit_line(points);
        std::vector<double> off;
        off.reserve(points.size());
        for (const auto& p : points)
            off.push_back(std::abs((p.x - line.point.x) * line.direction.y -
                                   (p.y - line.point.y) * line.direction.x));
        const double spread = 1.4826 * median_of(off);
        const double limit = pass < 3 ? std::max(4 * spread, 0.02) : settings.max_off_line_mm;
        std::vector<Point2> next;
        for (std::size_t k = 0; k < points.size(); ++k)
            if (off[k] <= limit) next.push_back(points[k]);
        if (next.size() == points.size() && pass < 3) continue;
        points = std::move(next);
    }
    return points;
}

// The points' span along the edge from `a` in direction `d`: the line is told by it.
double span_along(const std::vector<Point2>& points, Point2 a, Point2 d) {
    double span = 0;
    if (points.size() >= 2) {
        double lo = 1e300, hi = -1e300;
        for (const auto& p : points) {
            const double t = (p.x - a.x) * d.x + (p.y - a.y) * d.y;
            lo = std::min(lo, t), hi = std::max(hi, t);
        }
        span = hi - lo;
    }
    return span;
}

// One edge of the sheet, found in the photo along the rough outline's side.
struct EdgeFound {
    geometry::Line line;
    std::vector<Point2> points;  // machine mm, those on the line
    int stations = 0, under_glare = 0;
};

EdgeFound measure_edge(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                       const vision::GrayView& photo, const BedToMachine& map,
                       const RoughSheet& rough, int side, double surface_height_mm,
                       const StockSettings& settings) {
    const Point2 a = rough.corners[side], b = rough.corners[(side + 1) % 4];
    const double length = std::hypot(b.x - a.x, b.y - a.y);
    const Point2 d{(b.x - a.x) / length, (b.y - a.y) / length};
    const Point2 outward{d.y, -d.x};  // counter-clockwise: the sheet lies to the left
    // Each station's search from inside the sheet to the bed, its ends in the photo.
    std::vector<Point3> ends;
    const int last = static_cast<int>(
        std::floor((length - 2 * settings.corner_clearance_mm) / settings.station_step_mm));
    for (int i = 0; i <= last; ++i) {
        const double t = settings.corner_clearance_mm + i * settings.station_step_mm;
        const Point2 p{a.x + t * d.x, a.y + t * d.y};
        for (const double s : {-settings.search_half_mm, settings.search_half_mm}) {
            const Point2 bed = map.bed_of({p.x + s * outward.x, p.y + s * outward.y});
            ends.push_back({bed.x, bed.y, surface_height_mm});
        }
    }
    const std::size_t stations = ends.size() / 2;
    if (stations < 4)
        throw StockError("the sheet's " + std::string(kEdgeNames[side]) + " edge is " +
                         number_text("%.1f", length) +
                         " mm long: too short to measure clear of its corners");
    const auto ends_px = geometry::project_points(camera, plane.bed_to_camera, ends);
    std::vector<Point2> edge_px;
    int under_glare = 0;
    for (std::size_t k = 0; k < stations; ++k) {
        // From the sheet to the bed the photo steps down off a light sheet, up off a dark one.
        const auto e =
            vision::step_edge_on_segment(photo, ends_px[2 * k], ends_px[2 * k + 1], !rough.lighter);
        if (!e) continue;
        if (clipped_near(photo, *e, ends_px[2 * k], ends_px[2 * k + 1], settings)) {
            ++under_glare;
            continue;
        }
        edge_px.push_back(*e);
    }
    std::vector<Point2> points;
    if (!edge_px.empty())
        for (const Point3& p : geometry::pixels_to_bed(camera, plane, edge_px, surface_height_mm))
            points.push_back(map.machine_of({p.x, p.y}));
    points = on_the_line(std::move(points), settings);
    // The line is told by the points' span along it: what is left must reach over a share
    // of the edge (the ends of an edge whose middle lies under glare tell it well).
    const double span = span_along(points, a, d);
    const double reach = length - 2 * settings.corner_clearance_mm;
    if (points.size() < 8 || span < settings.min_span_share * reach)
        throw StockError("the sheet's " + std::string(kEdgeNames[side]) + " edge (" + at_text(a) +
                         " to " + at_text(b) + ") shows at " + std::to_string(points.size()) +
                         " of its " + std::to_string(stations) + " places (" +
                         std::to_string(under_glare) + " under glare), over " +
                         number_text("%.0f", span) + " of its " + number_text("%.0f", reach) +
                         " mm, under " + number_text("%.0f", 100 * settings.min_span_share) +
                         " %: it cannot be told there (point at the corner instead)");
    EdgeFound found;
    found.line = geometry::fit_line(points);
    found.stations = static_cast<int>(stations);
    found.under_glare = under_glare;
    found.points = std::move(points);
    return found;
}

}  // namespace

StockOutline find_stock(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                        const vision::GrayView& photo, const PlanarSolution& solution,
                        double surface_height_mm, const std::string& source,
                        const StockSettings& settings) {
    const BedToMachine map = planar_bed_to_machine(solution, source);
    const auto& f = *solution.frame;
    BedViewRequest rough_request;
    rough_request.surface_height_mm = surface_height_mm;
    rough_request.mm_per_px =
        std::max(f.travel_max_x_mm - f.travel_min_x_mm, f.travel_max_y_mm - f.travel_min_y_mm) /
        settings.rough_view_px;
    const BedView rough_view =
        render_bed_view(camera, plane, photo, solution, rough_request, source);
    const std::string area = "X " + number_text("%.1f", f.travel_min_x_mm) + ".." +
                             number_text("%.1f", f.travel_max_x_mm) + " Y " +
                             number_text("%.1f", f.travel_min_y_mm) + ".." +
                             number_text("%.1f", f.travel_max_y_mm) + " mm";
    const RoughSheet rough = rough_sheet(rough_view, area);

    StockOutline out;
    out.lighter_than_bed = rough.lighter;
    out.surface_height_mm = surface_height_mm;
    std::array<geometry::Line, 4> lines;
    std::array<std::vector<Point2>, 4> kept;
    for (int side = 0; side < 4; ++side) {
        EdgeFound edge =
            measure_edge(camera, plane, photo, map, rough, side, surface_height_mm, settings);
        lines[side] = edge.line;
        out.edge_points[side] = static_cast<int>(edge.points.size());
        out.edge_points_under_glare += edge.under_glare;
        out.edge_points_set_aside +=
            edge.stations - static_cast<int>(edge.points.size()) - edge.under_glare;
        kept[side] = std::move(edge.points);
    }
    // The camera's own part of each corner's uncertainty, the same everywhere (two sigma stated).
    const double camera_sigma = rough_view.accuracy_mm / 2;
    for (int k = 0; k < 4; ++k) {
        const int before = (k + 3) % 4;
        const auto corner = geometry::intersect(lines[before], lines[k]);
        const double sin_angle = std::abs(lines[before].direction.x * lines[k].direction.y -
                                          lines[before].direction.y * lines[k].direction.x);
        if (!corner || sin_angle < std::sin(30 * std::numbers::pi / 180))
            throw StockError("the sheet's " + std::string(kEdgeNames[before]) + " and " +
                             kEdgeNames[k] +
                             " edges meet at under 30 degrees: not a sheet's corner");
        const double across =
            std::hypot(geometry::line_sigma_at(lines[before], kept[before], *corner),
                       geometry::line_sigma_at(lines[k], kept[k], *corner)) /
            sin_angle;
        out.corners[k] = {kCornerNames[k], *corner, std::hypot(across, camera_sigma)};
    }
    // The front edge's line, pointed along +X.
    Point2 d = lines[0].direction;
    if (d.x < 0) d = {-d.x, -d.y};
    out.rotation_deg = std::atan2(d.y, d.x) * 180 / std::numbers::pi;
    const Point2 fl = out.corners[0].machine_mm, fr = out.corners[1].machine_mm,
                 bl = out.corners[3].machine_mm;
    out.width_mm = std::hypot(fr.x - fl.x, fr.y - fl.y);
    out.depth_mm = std::hypot(bl.x - fl.x, bl.y - fl.y);
    // The front line's turn: its two ends' uncertainties across it, over its length.
    out.rotation_sigma_deg = std::hypot(geometry::line_sigma_at(lines[0], kept[0], fl),
                                        geometry::line_sigma_at(lines[0], kept[0], fr)) /
                             out.width_mm * 180 / std::numbers::pi;
    return out;
}

std::vector<std::uint8_t> bed_view_with_stock(const BedView& view, const PlanarSolution& solution,
                                              const StockOutline& stock) {
    auto pixels = bed_view_with_overlay(view, solution);
    cv::Mat colour(view.pixels.height_px, view.pixels.width_px, CV_8UC3, pixels.data());
    constexpr int kShift = 4;
    const auto at = [&](Point2 machine) {
        const Point2 p = view.pixel_of_machine(machine);
        return cv::Point(static_cast<int>(std::lround((p.x + 0.5) * (1 << kShift))),
                         static_cast<int>(std::lround((p.y + 0.5) * (1 << kShift))));
    };
    const int thickness = std::max(1, static_cast<int>(std::lround(view.pixels.width_px / 800.0)));
    const cv::Scalar orange(0, 140, 255);
    const double font = std::max(0.4, view.pixels.width_px / 2400.0);
    for (int k = 0; k < 4; ++k) {
        const auto& c = stock.corners[k];
        cv::line(colour, at(c.machine_mm), at(stock.corners[(k + 1) % 4].machine_mm), orange,
                 thickness, cv::LINE_AA, kShift);
        cv::circle(colour, at(c.machine_mm), 6 * thickness << kShift, orange, thickness,
                   cv::LINE_AA, kShift);
        const Point2 p = view.pixel_of_machine(c.machine_mm);
        // Each name outside its corner, away from the sheet's middle.
        const Point2 middle{0.25 * (stock.corners[0].machine_mm.x + stock.corners[1].machine_mm.x +
                                    stock.corners[2].machine_mm.x + stock.corners[3].machine_mm.x),
                            0.25 * (stock.corners[0].machine_mm.y + stock.corners[1].machine_mm.y +
                                    stock.corners[2].machine_mm.y + stock.corners[3].machine_mm.y)};
        int baseline = 0;
        const cv::Size size =
            cv::getTextSize(c.name, cv::FONT_HERSHEY_SIMPLEX, font, thickness, &baseline);
        const int x = c.machine_mm.x < middle.x ? static_cast<int>(p.x) - size.width - 8
                                                : static_cast<int>(p.x) + 8;
        const int y = c.machine_mm.y < middle.y ? static_cast<int>(p.y) + size.height + 8
                                                : static_cast<int>(p.y) - 8;
        cv::putText(colour, c.name, {x, y}, cv::FONT_HERSHEY_SIMPLEX, font, orange, thickness,
                    cv::LINE_AA);
    }
    return pixels;
}

namespace {
constexpr const char* kStockSchema = "calbox.stock/1";
}  // namespace

std::string stock_to_json(const StockOutline& stock, const std::string& machine_fingerprint) {
    using nlohmann::json;
    json corners = json::array();
    for (const auto& c : stock.corners)
        corners.push_back(
            {{"name", c.name}, {"machine_mm", point_json(c.machine_mm)}, {"sigma_mm", c.sigma_mm}});
    const json j{{"schema", kStockSchema},
                 {"machine_fingerprint", machine_fingerprint},
                 {"corners", corners},
                 {"rotation_deg", stock.rotation_deg},
                 {"rotation_sigma_deg", stock.rotation_sigma_deg},
                 {"width_mm", stock.width_mm},
                 {"depth_mm", stock.depth_mm},
                 {"lighter_than_bed", stock.lighter_than_bed},
                 {"surface_height_mm", stock.surface_height_mm},
                 {"edge_points", stock.edge_points},
                 {"edge_points_set_aside", stock.edge_points_set_aside},
                 {"edge_points_under_glare", stock.edge_points_under_glare}};
    return j.dump(1) + "\n";
}

StockRecord stock_from_json(const std::string& text, const std::string& source) {
    const auto j = parse_record(text, source, kStockSchema, "stock");
    try {
        StockRecord r;
        r.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        const auto& corners = j.at("corners");
        if (!corners.is_array() || corners.size() != 4)
            throw RecordError(source + ": corners must list the sheet's four");
        for (std::size_t k = 0; k < 4; ++k) {
            auto& c = r.stock.corners[k];
            c.name = corners[k].at("name").get<std::string>();
            if (c.name != kCornerNames[k])
                throw RecordError(source + ": corner " + std::to_string(k) + " must be " +
                                  kCornerNames[k]);
            c.machine_mm = point_from(corners[k].at("machine_mm"));
            c.sigma_mm = corners[k].at("sigma_mm").get<double>();
            if (!std::isfinite(c.machine_mm.x) || !std::isfinite(c.machine_mm.y) ||
                !(c.sigma_mm >= 0))
                throw RecordError(source + ": corner " + c.name + " is not a finite place");
        }
        r.stock.rotation_deg = j.at("rotation_deg").get<double>();
        r.stock.rotation_sigma_deg = j.at("rotation_sigma_deg").get<double>();
        if (!(std::abs(r.stock.rotation_deg) <= 45))
            throw RecordError(source + ": rotation_deg is within +/-45 (the front edge's turn)");
        r.stock.width_mm = j.at("width_mm").get<double>();
        r.stock.depth_mm = j.at("depth_mm").get<double>();
        r.stock.lighter_than_bed = j.at("lighter_than_bed").get<bool>();
        r.stock.surface_height_mm = j.at("surface_height_mm").get<double>();
        r.stock.edge_points = j.at("edge_points").get<std::array<int, 4>>();
        r.stock.edge_points_set_aside = j.at("edge_points_set_aside").get<int>();
        r.stock.edge_points_under_glare = j.at("edge_points_under_glare").get<int>();
        return r;
    } catch (const nlohmann::json::exception& e) {
        throw RecordError(source + ": malformed stock file: " + e.what());
    }
}

const StockCorner& stock_corner(const StockOutline& stock, const std::string& name) {
    if (name == "nearest") {
        const auto& corners = stock.corners;
        return *std::min_element(corners.begin(), corners.end(), [](const auto& a, const auto& b) {
            return std::hypot(a.machine_mm.x, a.machine_mm.y) <
                   std::hypot(b.machine_mm.x, b.machine_mm.y);
        });
    }
    for (const auto& c : stock.corners)
        if (c.name == name) return c;
    throw StockError("'" + name +
                     "' is no corner of a sheet: give front-left, front-right, back-right, "
                     "back-left or nearest (the one nearest the machine's zero)");
}

}  // namespace calbox::modes
