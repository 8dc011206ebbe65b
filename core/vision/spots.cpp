#include "core/vision/spots.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/each_on_all_cores.hpp"
#include "core/geometry/cv_convert.hpp"
#include "core/median.hpp"
#include "core/vision/blobs.hpp"
#include "core/vision/local_threshold.hpp"
#include "core/vision/median_filter.hpp"

namespace calbox::vision {
namespace {

// Marks at least this wide in the photo are found on it at half its size (find_spots).
constexpr double kHalvedFromDiameterPx = 16;

// Second central moments -> major / minor axis ratio.
double elongation_of(double sxx, double syy, double sxy) {
    const double mean = 0.5 * (sxx + syy);
    const double spread = std::sqrt(0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy);
    const double minor = mean - spread, major = mean + spread;
    return minor > 0 ? std::sqrt(major / minor) : 1e9;
}

struct Ring {
    double level_dn = 0, noise_dn = 0;  // the substrate's level at the mark's centre, its noise
    double slope_x_dn_per_px = 0, slope_y_dn_per_px = 0;
    bool inside_image = true;
};

// Part of a photo and where its first pixel lies in the photo.
struct LocalView {
    GrayView view;
    int x0_px = 0, y0_px = 0;
};

// Which eighth of a turn from -pi an offset lies in: by its signs and which of |dx|, |dy| is the
// larger (an atan2 for each of a ring's thousand pixels was a tenth of a frame's time); on the
// eighths' edges, where rounding decides, as atan2 puts it.
int sector_of(double dx, double dy) {
    const double ax = std::abs(dx), ay = std::abs(dy);
    if (dx == 0 || dy == 0 || ax == ay) {
        const double turn = (std::atan2(dy, dx) + std::numbers::pi) / (2 * std::numbers::pi);
        return std::min(7, static_cast<int>(turn * 8));
    }
    const bool steep = ay > ax;
    if (dy < 0) return dx < 0 ? (steep ? 1 : 0) : (steep ? 2 : 3);
    return dx > 0 ? (steep ? 5 : 4) : (steep ? 6 : 7);
}

// The substrate around a mark from a ring just outside its window: a plane through the medians
// of eight sectors of the ring (a median, so that a neighbouring mark's edge in one sector does
// not move it; a plane, because the lamp's reflection climbs across a glossy plate), then the
// level at the centre and the spread as the median and the median absolute deviation of what the
// plane leaves.
Ring substrate_ring(const GrayView& image, geometry::Point2 c, double inner, double outer) {
    Ring ring;
    const int x0 = static_cast<int>(std::floor(c.x - outer)),
              x1 = static_cast<int>(std::ceil(c.x + outer));
    const int y0 = static_cast<int>(std::floor(c.y - outer)),
              y1 = static_cast<int>(std::ceil(c.y + outer));
    if (x0 < 0 || y0 < 0 || x1 >= image.width_px || y1 >= image.height_px) {
        ring.inside_image = false;
        return ring;
    }
    constexpr int kSectors = 8;
    struct Sample {
        double dx, dy, value;
    };
    std::vector<Sample> samples;
    const auto expected = static_cast<std::size_t>(
        std::numbers::pi * (outer * outer - inner * inner) + 8 * outer + 16);
    samples.reserve(expected);
    std::array<std::vector<double>, kSectors> sector_values;
    for (auto& values : sector_values) values.reserve(expected / kSectors + 16);
    std::array<double, kSectors> sector_x{}, sector_y{};
    // Each row is walked only across the ring's two spans, a pixel wider than they are on each
    // side (so that every pixel the exact test below takes is among those walked; walking the
    // whole square was most of a mark's time), in the same order as the square's walk.
    for (int y = y0; y <= y1; ++y) {
        const double dy = y - c.y;
        if (dy * dy > outer * outer) continue;
        const double outer_half = std::sqrt(outer * outer - dy * dy);
        const int first = std::max(x0, static_cast<int>(std::floor(c.x - outer_half)) - 1);
        const int last = std::min(x1, static_cast<int>(std::ceil(c.x + outer_half)) + 1);
        // Inside [hole_first, hole_last] every pixel lies more than a pixel inside the inner
        // circle.
        int hole_first = last + 1, hole_last = last;
        if (dy * dy < inner * inner) {
            const double inner_half = std::sqrt(inner * inner - dy * dy);
            hole_first = static_cast<int>(std::floor(c.x - inner_half)) + 2;
            hole_last = static_cast<int>(std::ceil(c.x + inner_half)) - 2;
        }
        for (int x = first; x <= last; ++x) {
            if (x == hole_first && hole_last >= hole_first) x = hole_last + 1;
            if (x > last) break;
            const double dx = x - c.x, d2 = dx * dx + dy * dy;
            if (d2 < inner * inner || d2 > outer * outer) continue;
            const double value = image.at(x, y);
            samples.push_back({dx, dy, value});
            const int k = sector_of(dx, dy);
            sector_values[static_cast<std::size_t>(k)].push_back(value);
            sector_x[static_cast<std::size_t>(k)] += dx;
            sector_y[static_cast<std::size_t>(k)] += dy;
        }
    }
    for (const auto& values : sector_values)
        if (values.size() < 3) {
            ring.inside_image = false;
            return ring;
        }
    // Least squares for level + slope . (x, y) through the sectors' medians at their centroids.
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d right = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < kSectors; ++k) {
        const double n = static_cast<double>(sector_values[k].size());
        const Eigen::Vector3d row{1.0, sector_x[k] / n, sector_y[k] / n};
        normal += row * row.transpose();
        right += row * median_of(std::move(sector_values[k]));
    }
    const Eigen::Vector3d plane = normal.ldlt().solve(right);
    ring.slope_x_dn_per_px = plane[1];
    ring.slope_y_dn_per_px = plane[2];
    std::vector<double> levels;
    levels.reserve(samples.size());
    for (const Sample& s : samples)
        levels.push_back(s.value - ring.slope_x_dn_per_px * s.dx - ring.slope_y_dn_per_px * s.dy);
    ring.level_dn = median_of(levels);
    std::vector<double> deviations;
    deviations.reserve(levels.size());
    for (double v : levels) deviations.push_back(std::abs(v - ring.level_dn));
    // A grey level is quantised: at least the quantisation noise of one count.
    ring.noise_dn = std::max(1.4826 * median_of(std::move(deviations)), 1 / std::sqrt(12.0));
    return ring;
}

double window_mean(const GrayView& image, geometry::Point2 c, double radius) {
    double sum = 0;
    int n = 0;
    for (int y = static_cast<int>(std::ceil(c.y - radius)); y <= static_cast<int>(c.y + radius);
         ++y)
        for (int x = static_cast<int>(std::ceil(c.x - radius)); x <= static_cast<int>(c.x + radius);
             ++x)
            if ((x - c.x) * (x - c.x) + (y - c.y) * (y - c.y) <= radius * radius)
                sum += image.at(x, y), ++n;
    return n > 0 ? sum / n : 0;
}

struct WindowBox {
    int cx = 0, cy = 0, reach = 0;  // integer centre and half size
    std::int64_t radius2_q16 = 0;   // window radius squared, Q16 pixels^2 about (cx, cy)
    double fx = 0, fy = 0;          // the window's true centre minus (cx, cy)
};

WindowBox box_of(const GrayView& image, const MomentWindow& w) {
    WindowBox b;
    b.cx = static_cast<int>(std::lround(w.centre_px.x));
    b.cy = static_cast<int>(std::lround(w.centre_px.y));
    b.reach = static_cast<int>(std::ceil(w.radius_px)) + 1;
    b.fx = w.centre_px.x - b.cx;
    b.fy = w.centre_px.y - b.cy;
    if (b.cx - b.reach < 0 || b.cy - b.reach < 0 || b.cx + b.reach >= image.width_px ||
        b.cy + b.reach >= image.height_px)
        throw std::invalid_argument("the spot's window leaves the image");
    return b;
}

}  // namespace

Spot measure_spot_q16(const GrayView& image, const MomentWindow& w) {
    image.check();
    const WindowBox b = box_of(image, w);
    const std::int64_t substrate_q8 = std::llround(w.substrate_dn * 256);
    const std::int64_t span_q8 = substrate_q8 - std::llround(w.mark_dn * 256);
    if (span_q8 == 0) throw std::invalid_argument("a spot needs contrast");
    // Window membership tested on Q8 offsets from the window's own centre.
    const std::int64_t fx_q8 = std::llround(b.fx * 256), fy_q8 = std::llround(b.fy * 256);
    const std::int64_t r_q8 = std::llround(w.radius_px * 256);
    const std::int64_t r2 = r_q8 * r_q8;
    const std::int64_t slope_x_q8 = std::llround(w.substrate_slope_x_dn_per_px * 256),
                       slope_y_q8 = std::llround(w.substrate_slope_y_dn_per_px * 256);
    std::int64_t s0 = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    std::int64_t free_n = 0, free_x = 0, free_y = 0, free_xx = 0, free_yy = 0;
    for (int dy = -b.reach; dy <= b.reach; ++dy) {
        const std::int64_t ey = std::int64_t{dy} * 256 - fy_q8;
        for (int dx = -b.reach; dx <= b.reach; ++dx) {
            const std::int64_t ex = std::int64_t{dx} * 256 - fx_q8;
            if (ex * ex + ey * ey > r2) continue;
            const std::int64_t level_q8 = static_cast<std::int64_t>(image.at(b.cx + dx, b.cy + dy))
                                          << 8;
            // Q8 slope times Q8 offset is Q16; an arithmetic shift back to Q8 on every platform.
            const std::int64_t here_q8 = substrate_q8 + ((slope_x_q8 * ex + slope_y_q8 * ey) >> 8);
            std::int64_t weight = (here_q8 - level_q8) * 65536 / span_q8;  // Q16
            if (weight > 0 && weight < 65536) {
                // Only a weight between its clamps moves with the noise.
                ++free_n;
                free_x += dx, free_y += dy;
                free_xx += std::int64_t{dx} * dx, free_yy += std::int64_t{dy} * dy;
            }
            weight = std::clamp<std::int64_t>(weight, 0, 65536);
            s0 += weight;
            sx += weight * dx;
            sy += weight * dy;
            sxx += weight * dx * dx;
            syy += weight * dy * dy;
            sxy += weight * dx * dy;
        }
    }
    if (s0 == 0) throw std::invalid_argument("no mark inside the spot's window");
    Spot spot;
    const double m0 = static_cast<double>(s0);
    const double mx = static_cast<double>(sx) / m0, my = static_cast<double>(sy) / m0;
    spot.centre_px = {b.cx + mx, b.cy + my};
    spot.area_px = m0 / 65536.0;
    spot.elongation = elongation_of(static_cast<double>(sxx) / m0 - mx * mx,
                                    static_cast<double>(syy) / m0 - my * my,
                                    static_cast<double>(sxy) / m0 - mx * my);
    spot.contrast_dn = std::abs(w.substrate_dn - w.mark_dn);
    // Each free weight has noise noise/span; its pull on the centroid is (x - mean) / area.
    const double n = static_cast<double>(free_n);
    const double spread2 =
        0.5 * (static_cast<double>(free_xx) - 2 * mx * static_cast<double>(free_x) + n * mx * mx +
               static_cast<double>(free_yy) - 2 * my * static_cast<double>(free_y) + n * my * my);
    spot.sigma_px =
        w.noise_dn / spot.contrast_dn * std::sqrt(std::max(0.0, spread2)) / spot.area_px;
    return spot;
}

Spot measure_spot_reference(const GrayView& image, const MomentWindow& w) {
    image.check();
    const WindowBox b = box_of(image, w);
    const double span = w.substrate_dn - w.mark_dn;
    double s0 = 0, sx = 0, sy = 0;
    for (int dy = -b.reach; dy <= b.reach; ++dy)
        for (int dx = -b.reach; dx <= b.reach; ++dx) {
            if ((dx - b.fx) * (dx - b.fx) + (dy - b.fy) * (dy - b.fy) > w.radius_px * w.radius_px)
                continue;
            const double here = w.substrate_dn + w.substrate_slope_x_dn_per_px * (dx - b.fx) +
                                w.substrate_slope_y_dn_per_px * (dy - b.fy);
            const double weight =
                std::clamp((here - image.at(b.cx + dx, b.cy + dy)) / span, 0.0, 1.0);
            s0 += weight, sx += weight * (b.cx + dx), sy += weight * (b.cy + dy);
        }
    Spot spot;
    spot.centre_px = {sx / s0, sy / s0};
    spot.area_px = s0;
    spot.contrast_dn = std::abs(span);
    return spot;
}

namespace {

// The marks' mask on `found_filtered`: a local threshold where the marks' size is known, else
// Otsu's level (kept in `out`). Halved, the halved photo is not read again: its buffer takes
// the mask.
cv::Mat mark_mask(const cv::Mat& found_filtered, const cv::Mat& found_on, bool halved,
                  const SpotSettings& settings, SpotImage& out) {
    cv::Mat marks;
    if (settings.mark_diameter_px > 0) {
        const double diameter = settings.mark_diameter_px / (halved ? 2 : 1);
        const int block =
            std::max(halved ? 7 : 15, 2 * static_cast<int>(std::lround(1.5 * diameter)) + 1);
        if (halved) marks = found_on;
        local_threshold(found_filtered, block, out.dark_marks, settings.local_contrast_dn, marks);
        return marks;
    }
    // Otsu's level from a reduced copy: the histogram is the same, a tenth of the work. (The
    // photo is halved only for marks of a known size: here it is the whole photo.)
    cv::Mat small;
    const double shrink =
        std::min(1.0, std::sqrt(1.5e6 / static_cast<double>(found_filtered.total())));
    cv::resize(found_filtered, small, cv::Size(), shrink, shrink, cv::INTER_AREA);
    cv::Mat ignored;
    out.threshold_dn = cv::threshold(small, ignored, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
    return out.dark_marks ? (found_filtered <= out.threshold_dn)
                          : (found_filtered > out.threshold_dn);
}

struct SpotCandidate {
    geometry::Point2 rough;
    int area_px = 0;
};

// The blobs large enough and inside the search outline, at the photo's scale.
std::vector<SpotCandidate> spot_candidates(const std::vector<Blob>& blobs, int scale,
                                           const SpotSettings& settings) {
    std::vector<cv::Point2f> outline;
    for (const auto& p : settings.search_outline_px)
        outline.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
    std::vector<SpotCandidate> candidates;
    candidates.reserve(blobs.size());
    for (const Blob& blob : blobs) {
        const int area = static_cast<int>(blob.area_px) * scale * scale;
        if (area < settings.min_area_px) continue;
        // A pixel of the halved photo covers two of the photo's: its centre lies half a pixel on.
        const geometry::Point2 rough{scale * blob.centre_x_px + 0.5 * (scale - 1),
                                     scale * blob.centre_y_px + 0.5 * (scale - 1)};
        if (outline.size() >= 3 &&
            cv::pointPolygonTest(
                outline, cv::Point2f(static_cast<float>(rough.x), static_cast<float>(rough.y)),
                false) < 0)
            continue;
        candidates.push_back({rough, area});
    }
    return candidates;
}

// The median-filtered photo a mark is measured on. Halved, each mark's own patch of the full
// photo, median-filtered around it alone, reaching the kernel's half further than what is kept
// so that the patch's own border lies outside it, as the whole photo's would. The patch is read
// with the mark's coordinates moved by the patch's corner, an integer, so that every figure is
// the one the whole photo's median gives (a 12 MP buffer touched around each mark cost a page
// fault for each row of every patch).
class FilteredPhoto {
  public:
    FilteredPhoto(const cv::Mat& raw, const cv::Mat& found_filtered, bool halved,
                  int median_kernel_px)
        : raw_(raw),
          found_filtered_(found_filtered),
          halved_(halved),
          median_kernel_px_(median_kernel_px) {}

    LocalView around(geometry::Point2 centre, double reach, cv::Mat& patch) const {
        if (!halved_)
            return {{found_filtered_.data, found_filtered_.cols, found_filtered_.rows,
                     static_cast<int>(found_filtered_.step)},
                    0,
                    0};
        const cv::Rect inside(0, 0, raw_.cols, raw_.rows);
        const int median_reach = median_kernel_px_ / 2;
        const cv::Rect wanted(static_cast<int>(std::floor(centre.x - reach)) - 1,
                              static_cast<int>(std::floor(centre.y - reach)) - 1,
                              static_cast<int>(2 * std::ceil(reach)) + 4,
                              static_cast<int>(2 * std::ceil(reach)) + 4);
        const cv::Rect area = wanted & inside;
        if (area.empty()) return {};
        const cv::Rect input =
            cv::Rect(area.x - median_reach, area.y - median_reach, area.width + 2 * median_reach,
                     area.height + 2 * median_reach) &
            inside;
        patch = median_filtered(raw_(input), median_kernel_px_);
        const cv::Mat kept =
            patch(cv::Rect(area.x - input.x, area.y - input.y, area.width, area.height));
        return {{kept.data, kept.cols, kept.rows, static_cast<int>(kept.step)}, area.x, area.y};
    }

  private:
    const cv::Mat& raw_;
    const cv::Mat& found_filtered_;
    bool halved_;
    int median_kernel_px_;
};

// One mark measured: its substrate from the ring around it, then its moments; none where it
// shows no real contrast, a border mark where the ring leaves the photo.
std::optional<Spot> measure_candidate(const SpotCandidate& candidate, const FilteredPhoto& photo,
                                      const SpotSettings& settings) {
    const auto [rough, area] = candidate;
    const double radius = std::sqrt(area / 3.14159265358979) + settings.window_margin_px;
    cv::Mat patch;
    const LocalView local = photo.around(rough, radius + 4, patch);
    const geometry::Point2 here{rough.x - local.x0_px, rough.y - local.y0_px};
    const Ring ring = local.view.pixels == nullptr
                          ? Ring{.inside_image = false}
                          : substrate_ring(local.view, here, radius + 1, radius + 4);
    Spot spot;
    if (!ring.inside_image) {
        spot.centre_px = rough;
        spot.area_px = area;
        spot.touches_border = true;
        return spot;
    }
    MomentWindow window;
    window.centre_px = here;
    window.radius_px = radius;
    window.substrate_dn = ring.level_dn;
    window.substrate_slope_x_dn_per_px = ring.slope_x_dn_per_px;
    window.substrate_slope_y_dn_per_px = ring.slope_y_dn_per_px;
    window.mark_dn = window_mean(local.view, here, 0.5 * (radius - settings.window_margin_px));
    window.noise_dn = ring.noise_dn;
    if (std::abs(window.substrate_dn - window.mark_dn) < 4) return std::nullopt;
    spot = measure_spot_q16(local.view, window);
    spot.centre_px = {spot.centre_px.x + local.x0_px, spot.centre_px.y + local.y0_px};
    return spot;
}

}  // namespace

SpotImage find_spots(const GrayView& view, const SpotSettings& settings) {
    view.check();
    const cv::Mat raw = geometry::to_cv(view);
    SpotImage out;
    out.dark_marks = settings.polarity == MarkPolarity::dark;
    // Where the marks are is found on the photo at half its size when they are large enough to
    // keep their shape there (a quarter of the pixels through the median, the local threshold
    // and the labelling, which were most of a 12 MP frame's time); each mark is then measured on
    // the full photo, median-filtered around it alone, exactly as the whole photo's median gives
    // it there.
    const bool halved = settings.mark_diameter_px >= kHalvedFromDiameterPx;
    const int scale = halved ? 2 : 1;
    cv::Mat found_on;
    if (halved)
        cv::resize(raw, found_on, cv::Size((raw.cols + 1) / 2, (raw.rows + 1) / 2), 0, 0,
                   cv::INTER_AREA);
    else
        found_on = raw;
    const cv::Mat found_filtered =
        median_filtered(found_on, halved ? 3 : settings.median_kernel_px);
    const cv::Mat marks = mark_mask(found_filtered, found_on, halved, settings, out);
    const std::vector<SpotCandidate> candidates = spot_candidates(blobs_of(marks), scale, settings);
    const FilteredPhoto photo(raw, found_filtered, halved, settings.median_kernel_px);
    // Each mark measured apart from the others, on all the cores (the marks were most of a
    // frame's time on one), into a slot of its own, then kept in the blobs' order.
    std::vector<std::optional<Spot>> measured(candidates.size());
    each_on_all_cores(candidates.size(), [&](std::size_t i) {
        measured[i] = measure_candidate(candidates[i], photo, settings);
    });
    for (const auto& spot : measured)
        if (spot) out.spots.push_back(*spot);
    return out;
}

}  // namespace calbox::vision
