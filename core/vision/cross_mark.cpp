#include "core/vision/cross_mark.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <vector>

#include "core/geometry/line_fit.hpp"
#include "core/vision/edge_kernel.hpp"

namespace calbox::vision {
namespace {

using geometry::Point2;

// Samples every `step` from `from`, in grey levels; empty when a sample leaves the image.
std::vector<double> samples(const GrayView& image, Point2 from, Point2 step, int count) {
    std::vector<std::int32_t> q8(static_cast<std::size_t>(count));
    if (!sample_profile_q8(image, to_q16(from.x), to_q16(from.y), to_q16(step.x), to_q16(step.y),
                           count, q8.data()))
        return {};
    std::vector<double> grey(q8.size());
    std::transform(q8.begin(), q8.end(), grey.begin(),
                   [](std::int32_t v) { return static_cast<double>(v) / 256; });
    return grey;
}

Point2 along(Point2 p, Point2 d, double t) {
    return {p.x + d.x * t, p.y + d.y * t};
}

}  // namespace

std::optional<CrossCentre> measure_cross(const GrayView& image, Point2 rough_px, double span_px,
                                         double bar_px) {
    const double reach = span_px / 2 - bar_px;  // the arms' stations end a bar short of the tips
    const double clear = 1.5 * bar_px + 1;      // and start clear of the other bar
    if (!(reach > clear + 2)) return std::nullopt;
    // The bars' turn: the one of a degree's steps along which the four arms are darkest (a plus
    // has no second-moment direction of its own).
    double best_score = -1, best_deg = 0;
    const int ray = static_cast<int>(std::ceil(reach - clear)) + 1;
    for (int deg = 0; deg < 90; ++deg) {
        const double a = deg * std::numbers::pi / 180;
        double score = 0;
        for (int arm = 0; arm < 4; ++arm) {
            const Point2 u{std::cos(a + arm * std::numbers::pi / 2),
                           std::sin(a + arm * std::numbers::pi / 2)};
            const auto grey = samples(image, along(rough_px, u, clear), u, ray);
            if (grey.empty()) return std::nullopt;
            score += 255.0 * static_cast<double>(grey.size()) -
                     std::accumulate(grey.begin(), grey.end(), 0.0);
        }
        if (score > best_score) best_score = score, best_deg = deg;
    }
    // Each bar across at every pixel of both its arms: the darkness's centroid on a profile
    // two and a half bars either side (the bright paper beyond is the level it is measured from).
    const double half = 2.5 * bar_px + 2;
    constexpr double kStep = 0.125;
    const int count = static_cast<int>(std::ceil(2 * half / kStep)) + 1;
    CrossCentre found;
    found.turn_deg = best_deg;
    std::vector<geometry::Line> bars;
    std::vector<std::vector<Point2>> bar_points;
    for (int bar = 0; bar < 2; ++bar) {
        const double a = (best_deg + 90.0 * bar) * std::numbers::pi / 180;
        const Point2 u{std::cos(a), std::sin(a)}, n{-u.y, u.x};
        std::vector<Point2> points;
        const int stations = static_cast<int>(std::floor(reach));
        for (int station = -stations; station <= stations; ++station) {
            const double s = station;
            if (std::abs(s) < clear) continue;
            const Point2 middle = along(rough_px, u, s);
            const auto grey =
                samples(image, along(middle, n, -half), {n.x * kStep, n.y * kStep}, count);
            if (grey.empty()) continue;
            // The paper's level: the brighter of the profile's two ends.
            const std::size_t end = grey.size() / 6;
            const double left = std::accumulate(grey.begin(), grey.begin() + end, 0.0) / end;
            const double right = std::accumulate(grey.end() - end, grey.end(), 0.0) / end;
            const double paper = std::max(left, right);
            double weight = 0, moment = 0;
            for (std::size_t k = 0; k < grey.size(); ++k) {
                const double w = std::max(0.0, paper - grey[k]);
                weight += w;
                moment += w * static_cast<double>(k);
            }
            // A station without a bar's worth of darkness is not on the bar.
            const double depth = *std::max_element(grey.begin(), grey.end()) -
                                 *std::min_element(grey.begin(), grey.end());
            if (!(weight > 0) || depth < 20) continue;
            points.push_back(along(middle, n, -half + moment / weight * kStep));
        }
        if (points.size() < 6) return std::nullopt;
        bars.push_back(geometry::fit_line(points));
        bar_points.push_back(std::move(points));
    }
    const auto centre = geometry::intersect(bars[0], bars[1]);
    if (!centre) return std::nullopt;
    found.centre_px = *centre;
    // Neighbouring stations share the blur's reach: about one in two counts as independent.
    found.sigma_px = std::max(geometry::line_sigma_at(bars[0], bar_points[0], *centre, 0.5),
                              geometry::line_sigma_at(bars[1], bar_points[1], *centre, 0.5));
    found.profiles = static_cast<int>(bar_points[0].size() + bar_points[1].size());
    return found;
}

}  // namespace calbox::vision
