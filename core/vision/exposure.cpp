#include "core/vision/exposure.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/number_text.hpp"

namespace calbox::vision {
namespace {

// The level below which `share` of a histogram's counts lie.
double percentile_of(const std::array<std::size_t, 256>& histogram, std::size_t count,
                     double share) {
    const auto wanted = static_cast<std::size_t>(std::ceil(share * static_cast<double>(count)));
    std::size_t seen = 0;
    for (std::size_t level = 0; level < histogram.size(); ++level) {
        seen += histogram[level];
        if (seen >= wanted) return static_cast<double>(level);
    }
    return 255;
}

}  // namespace

std::vector<geometry::Point2> work_area_inside(const std::vector<geometry::Point2>& mark_centres_px,
                                               int width_px, int height_px, double border_share) {
    if (mark_centres_px.size() < 3) {
        const double bx = border_share * width_px, by = border_share * height_px;
        return {{bx, by},
                {width_px - 1 - bx, by},
                {width_px - 1 - bx, height_px - 1 - by},
                {bx, height_px - 1 - by}};
    }
    std::vector<cv::Point2f> points, hull;
    points.reserve(mark_centres_px.size());
    for (const auto& p : mark_centres_px)
        points.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
    cv::convexHull(points, hull);
    double mx = 0, my = 0;
    for (const auto& p : hull) mx += p.x, my += p.y;
    mx /= static_cast<double>(hull.size()), my /= static_cast<double>(hull.size());
    std::vector<geometry::Point2> area;
    area.reserve(hull.size());
    for (const auto& p : hull) area.push_back({p.x + 0.1 * (mx - p.x), p.y + 0.1 * (my - p.y)});
    return area;
}

WorkAreaLight meter_work_area(const GrayView& frame, const std::vector<geometry::Point2>& area_px,
                              const MeteringLimits& limits) {
    frame.check();
    if (area_px.size() < 3) throw std::invalid_argument("a work area needs at least three corners");
    double left = frame.width_px, top = frame.height_px, right = 0, bottom = 0;
    for (const auto& p : area_px) {
        left = std::min(left, p.x), right = std::max(right, p.x);
        top = std::min(top, p.y), bottom = std::max(bottom, p.y);
    }
    const int x0 = std::max(0, static_cast<int>(std::floor(left)));
    const int y0 = std::max(0, static_cast<int>(std::floor(top)));
    const int x1 = std::min(frame.width_px, static_cast<int>(std::ceil(right)) + 1);
    const int y1 = std::min(frame.height_px, static_cast<int>(std::ceil(bottom)) + 1);
    if (x1 - x0 < 2 || y1 - y0 < 2)
        throw std::invalid_argument("the work area is outside the frame");
    cv::Mat inside = cv::Mat::zeros(y1 - y0, x1 - x0, CV_8U);
    std::vector<cv::Point> corners;
    corners.reserve(area_px.size());
    for (const auto& p : area_px)
        corners.emplace_back(static_cast<int>(std::lround(p.x)) - x0,
                             static_cast<int>(std::lround(p.y)) - y0);
    cv::fillPoly(inside, std::vector<std::vector<cv::Point>>{corners}, cv::Scalar(255));

    const int tiles_x = std::max(1, limits.tiles_across);
    const int tiles_y =
        std::max(1, static_cast<int>(std::lround(tiles_x * static_cast<double>(y1 - y0) /
                                                 static_cast<double>(x1 - x0))));
    WorkAreaLight light;
    std::vector<double> tile_light;
    std::size_t clipped = 0;
    for (int ty = 0; ty < tiles_y; ++ty) {
        for (int tx = 0; tx < tiles_x; ++tx) {
            const int u0 = (x1 - x0) * tx / tiles_x, u1 = (x1 - x0) * (tx + 1) / tiles_x;
            const int v0 = (y1 - y0) * ty / tiles_y, v1 = (y1 - y0) * (ty + 1) / tiles_y;
            std::array<std::size_t, 256> histogram{};
            std::size_t count = 0;
            for (int v = v0; v < v1; ++v) {
                const std::uint8_t* mask = inside.ptr<std::uint8_t>(v);
                for (int u = u0; u < u1; ++u) {
                    if (mask[u] == 0) continue;
                    const std::uint8_t level = frame.at(x0 + u, y0 + v);
                    ++histogram[level];
                    ++count;
                    if (level >= limits.clipped_from_dn) ++clipped;
                }
            }
            light.pixels += count;
            const auto box = static_cast<double>((u1 - u0) * (v1 - v0));
            if (count == 0 || static_cast<double>(count) < limits.smallest_tile_share * box)
                continue;
            tile_light.push_back(percentile_of(histogram, count, limits.tile_brightest_percentile));
        }
    }
    if (tile_light.empty()) throw std::invalid_argument("the work area is outside the frame");
    std::sort(tile_light.begin(), tile_light.end());
    light.bright_dn = tile_light.back();
    light.typical_dn = tile_light[tile_light.size() / 2];
    light.dark_dn = tile_light[static_cast<std::size_t>(
        std::floor(limits.dark_side_tile_share * static_cast<double>(tile_light.size() - 1)))];
    light.clipped_share = static_cast<double>(clipped) / static_cast<double>(light.pixels);
    return light;
}

ExposurePlan plan_exposure(const WorkAreaLight& light, const MeteringLimits& limits,
                           bool after_cuts) {
    ExposurePlan plan;
    const std::string read = "the work area's bright side " + number_text("%.0f", light.bright_dn) +
                             ", its dark side " + number_text("%.0f", light.dark_dn) + " (" +
                             number_text("%.1f", 100 * light.clipped_share) + " % clipped)";
    if (light.bright_dn >= limits.clipped_from_dn) {
        plan.step = ExposurePlan::Step::meter_again;
        plan.ratio = 0.5;
        plan.why = read + ": read again at half the exposure";
        return plan;
    }
    const auto clamp = [&](double r) {
        return std::clamp(r, limits.smallest_ratio, limits.largest_ratio);
    };
    // A bright side already near the target is held as it is (a capture saved).
    const bool held = light.bright_dn >= limits.bright_good_share * limits.bright_target_dn;
    const double ratio =
        held ? 1.0 : clamp(limits.bright_target_dn / std::max(light.bright_dn, 1.0));
    const double dark_then = light.dark_dn * ratio;
    // The long exposure lifts the dark side to its least, or the middle of the work area to the
    // target where a hot spot holds the single exposure down.
    const double typical_then = light.typical_dn * ratio;
    const bool typical_low =
        after_cuts && typical_then < limits.typical_least_share * limits.bright_target_dn;
    const double long_ratio = clamp(
        std::max(limits.dark_least_dn / std::max(light.dark_dn, 1.0),
                 typical_low ? limits.bright_target_dn / std::max(light.typical_dn, 1.0) : 0.0));
    const std::string single_why = held ? read + ": held as it is"
                                        : read + ": x" + number_text("%.2f", ratio) +
                                              " puts them at " +
                                              number_text("%.0f", light.bright_dn * ratio) +
                                              " and " + number_text("%.0f", dark_then);
    if ((dark_then >= limits.dark_least_dn && !typical_low) ||
        long_ratio < limits.bracket_worth * ratio) {
        plan.step = ExposurePlan::Step::single;
        plan.ratio = ratio;
        plan.why = single_why;
        return plan;
    }
    plan.step = ExposurePlan::Step::bracket;
    plan.ratio = long_ratio;
    plan.short_ratio = ratio;
    plan.why = read + ": one exposure cannot hold both: x" + number_text("%.2f", long_ratio) +
               (typical_low ? " for the work area's middle (" +
                                  number_text("%.0f", light.typical_dn) + " there)"
                            : std::string(" for the dark side")) +
               ", x" + number_text("%.2f", ratio) + " for the bright, merged";
    return plan;
}

MergedFrame merge_bracket(const GrayView& long_frame, const GrayView& short_frame,
                          double long_over_short, const MeteringLimits& limits) {
    long_frame.check();
    short_frame.check();
    if (long_frame.width_px != short_frame.width_px ||
        long_frame.height_px != short_frame.height_px)
        throw std::invalid_argument("a bracket's frames differ in size");
    if (!(long_over_short >= 1))
        throw std::invalid_argument("a bracket's long exposure must be the longer");
    MergedFrame out{long_frame.width_px, long_frame.height_px, {}, 0};
    out.pixels.resize(static_cast<std::size_t>(out.width_px) * out.height_px);
    std::size_t from_short = 0;
    std::size_t i = 0;
    for (int y = 0; y < out.height_px; ++y) {
        for (int x = 0; x < out.width_px; ++x, ++i) {
            const std::uint8_t l = long_frame.at(x, y);
            if (l >= limits.clipped_from_dn) {
                out.pixels[i] = short_frame.at(x, y);
                ++from_short;
            } else {
                out.pixels[i] = static_cast<std::uint8_t>(
                    std::min(255L, std::lround(static_cast<double>(l) / long_over_short)));
            }
        }
    }
    out.from_short_share = static_cast<double>(from_short) / static_cast<double>(i);
    return out;
}

int otsu_level(const std::array<double, 256>& histogram) {
    double total = 0, level_sum = 0;
    for (std::size_t level = 0; level < histogram.size(); ++level) {
        total += histogram[level];
        level_sum += static_cast<double>(level) * histogram[level];
    }
    if (!(total > 0)) return 0;
    const double scale = 1 / total;
    const double mean = level_sum * scale;
    // The dark class's share and mean as the level rises; a level that leaves a class emptier
    // than float's resolution is passed over (as OpenCV does, its running mean included).
    double dark_share = 0, dark_mean = 0, best_spread = 0;
    int best = 0;
    constexpr double kEmpty = std::numeric_limits<float>::epsilon();
    for (std::size_t level = 0; level < histogram.size(); ++level) {
        const double share = histogram[level] * scale;
        dark_mean *= dark_share;
        dark_share += share;
        const double bright_share = 1 - dark_share;
        if (std::min(dark_share, bright_share) < kEmpty ||
            std::max(dark_share, bright_share) > 1 - kEmpty)
            continue;
        dark_mean = (dark_mean + static_cast<double>(level) * share) / dark_share;
        const double bright_mean = (mean - dark_share * dark_mean) / bright_share;
        const double spread =
            dark_share * bright_share * (dark_mean - bright_mean) * (dark_mean - bright_mean);
        if (spread > best_spread) {
            best_spread = spread;
            best = static_cast<int>(level);
        }
    }
    return best;
}

}  // namespace calbox::vision
