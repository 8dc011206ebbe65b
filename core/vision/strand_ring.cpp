#include "core/vision/strand_ring.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <stdexcept>
#include <vector>

#include "core/geometry/line_fit.hpp"
#include "core/median.hpp"
#include "core/number_text.hpp"

namespace calbox::vision {
namespace {

using geometry::Point2;

// The marker's (and the ring's) corners in its own millimetres, in OpenCV's order as printed.
std::array<Point2, 4> square_corners(double half) {
    return {Point2{-half, half}, Point2{half, half}, Point2{half, -half}, Point2{-half, -half}};
}

// Marker millimetres -> the coordinates edges are fitted in (undistorted normalized with a
// camera, raw pixels without) and -> raw pixels.
class MarkerFrame {
  public:
    MarkerFrame(const std::array<Point2, 4>& marker_corners_px, double marker_half,
                const geometry::CameraModel* camera)
        : camera_(camera) {
        std::vector<Point2> seen(marker_corners_px.begin(), marker_corners_px.end());
        if (camera_ != nullptr) seen = geometry::undistort_to_normalized(*camera_, seen);
        const auto local = square_corners(marker_half);
        std::array<cv::Point2f, 4> from{}, to{};
        for (std::size_t k = 0; k < 4; ++k) {
            from[k] = cv::Point2f(static_cast<float>(local[k].x), static_cast<float>(local[k].y));
            to[k] = cv::Point2f(static_cast<float>(seen[k].x), static_cast<float>(seen[k].y));
        }
        homography_ = cv::getPerspectiveTransform(from.data(), to.data());
    }
    Point2 to_fit_space(Point2 local) const {
        const auto& h = homography_;
        const double w =
            h.at<double>(2, 0) * local.x + h.at<double>(2, 1) * local.y + h.at<double>(2, 2);
        return {
            (h.at<double>(0, 0) * local.x + h.at<double>(0, 1) * local.y + h.at<double>(0, 2)) / w,
            (h.at<double>(1, 0) * local.x + h.at<double>(1, 1) * local.y + h.at<double>(1, 2)) / w};
    }
    std::vector<Point2> to_pixels(const std::vector<Point2>& fit_space) const {
        return camera_ != nullptr ? geometry::distort_from_normalized(*camera_, fit_space)
                                  : fit_space;
    }
    std::vector<Point2> from_pixels(const std::vector<Point2>& pixels) const {
        return camera_ != nullptr ? geometry::undistort_to_normalized(*camera_, pixels) : pixels;
    }
    double pixels_per_unit() const { return camera_ != nullptr ? camera_->fx() : 1.0; }

  private:
    const geometry::CameraModel* camera_;
    cv::Mat homography_;
};

// One side's profiles: where along the side (0 at its first corner, 1 at its second), the
// centreline point (fit space) and the strand's width there (pixels).
struct SideProfiles {
    std::vector<double> t;
    std::vector<Point2> centre;
    std::vector<double> width_t;  // where the width was fitted: most of `t`
    std::vector<double> width_px;
    std::string widths_unmeasured_because;
};

// Least-squares straight line through (t, v): its value at t0 and that value's standard
// uncertainty from the scatter.
struct ValueAt {
    double value = 0, sigma = 0;
};
ValueAt plain_linear_fit_at(const std::vector<double>& t, const std::vector<double>& v, double t0);

// The same, with the points more than four robust deviations off a first fit left out: a
// profile whose edge was a speck or a neighbour's gives a width far off the side's trend.
ValueAt linear_fit_at(const std::vector<double>& t, const std::vector<double>& v, double t0) {
    std::vector<double> residuals;
    for (std::size_t i = 0; i < t.size(); ++i)
        residuals.push_back(std::abs(v[i] - plain_linear_fit_at(t, v, t[i]).value));
    const double robust_sigma = 1.4826 * median_of(residuals);
    std::vector<double> kept_t, kept_v;
    for (std::size_t i = 0; i < t.size(); ++i) {
        if (residuals[i] <= 4 * robust_sigma + 1e-9) kept_t.push_back(t[i]), kept_v.push_back(v[i]);
    }
    return kept_t.size() >= 3 ? plain_linear_fit_at(kept_t, kept_v, t0)
                              : plain_linear_fit_at(t, v, t0);
}

ValueAt plain_linear_fit_at(const std::vector<double>& t, const std::vector<double>& v, double t0) {
    const double n = static_cast<double>(t.size());
    double mt = 0, mv = 0;
    for (std::size_t i = 0; i < t.size(); ++i) mt += t[i], mv += v[i];
    mt /= n, mv /= n;
    double stt = 0, stv = 0;
    for (std::size_t i = 0; i < t.size(); ++i) {
        stt += (t[i] - mt) * (t[i] - mt);
        stv += (t[i] - mt) * (v[i] - mv);
    }
    const double slope = stt > 0 ? stv / stt : 0;
    double ss = 0;
    for (std::size_t i = 0; i < t.size(); ++i) {
        const double r = v[i] - mv - slope * (t[i] - mt);
        ss += r * r;
    }
    const double s2 = n > 2 ? ss / (n - 2) : 0;
    const double dt = t0 - mt;
    return {mv + slope * dt, std::sqrt(s2 * (1 / n + (stt > 0 ? dt * dt / stt : 0)))};
}

// The image's grey level at a point (bilinear, the measurement kernels' own sampler); empty
// off the image.
std::optional<double> grey_at(const GrayView& image, Point2 at) {
    std::int32_t q8 = 0;
    if (!sample_profile_q8(image, to_q16(at.x), to_q16(at.y), 0, 0, 1, &q8)) return std::nullopt;
    return q8 / 256.0;
}

// The standard normal's distribution and density, read from a table by cubic Hermite
// interpolation (each node's slope is the density there, and the density's is -u times it): within
// 2e-9 of erfc and exp everywhere, where those two were a tenth of a frame's measuring time (the
// bar fit evaluates them for every sample of every profile at every step).
struct NormalAt {
    double cdf = 0, pdf = 0;
};
class NormalTable {
  public:
    NormalTable() {
        for (std::size_t i = 0; i < kNodes; ++i) {
            const double u = -kReach + static_cast<double>(i) / kPerUnit;
            cdf_[i] = 0.5 * std::erfc(-u / std::sqrt(2.0));
            pdf_[i] = kInvSqrt2Pi * std::exp(-0.5 * u * u);
        }
    }
    NormalAt operator()(double u) const {
        // A step gone to NaN must give a NaN cost, as erfc does, so that it is refused.
        if (std::isnan(u)) return {u, u};
        if (!(u > -kReach)) return {0, 0};
        if (!(u < kReach)) return {1, 0};
        const double t = (u + kReach) * kPerUnit;
        const auto i = std::min(static_cast<std::size_t>(t), kNodes - 2);
        const double s = t - static_cast<double>(i), h = 1.0 / kPerUnit;
        const double s2 = s * s, s3 = s2 * s;
        const double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2,
                     h11 = s3 - s2;
        const double u0 = -kReach + static_cast<double>(i) * h, u1 = u0 + h;
        return {h00 * cdf_[i] + h10 * h * pdf_[i] + h01 * cdf_[i + 1] + h11 * h * pdf_[i + 1],
                h00 * pdf_[i] - h10 * h * u0 * pdf_[i] + h01 * pdf_[i + 1] -
                    h11 * h * u1 * pdf_[i + 1]};
    }

  private:
    static constexpr double kInvSqrt2Pi = 0.3989422804014327;
    // Past 8 sigma the distribution is 0 or 1 to 1e-15.
    static constexpr double kReach = 8;
    static constexpr double kPerUnit = 32;
    static constexpr std::size_t kNodes = static_cast<std::size_t>(2 * kReach * kPerUnit) + 1;
    std::array<double, kNodes> cdf_{}, pdf_{};
};

const NormalTable& normal_table() {
    static const NormalTable table;
    return table;
}

// Where consecutive sides' centrelines meet, in the fit space; none when two run parallel.
std::optional<std::vector<Point2>> where_sides_meet(const std::array<geometry::Line, 4>& lines) {
    std::vector<Point2> corners;
    for (std::size_t k = 0; k < 4; ++k) {
        const auto c = geometry::intersect(lines[(k + 3) % 4], lines[k]);
        if (!c) return std::nullopt;
        corners.push_back(*c);
    }
    return corners;
}

}  // namespace

namespace {

// Levenberg-Marquardt over the bar's (level, slope, brightness, centre, width, blur), the slope
// about the starting centre so that it and the level do not trade; with `Free` 4, over the
// first, second, fourth and fifth alone (brightness and blur held): a held parameter's row of the
// normal equations is zero but for its diagonal, so its step is zero and the others' are those
// of the smaller system, which is solved instead.
template <int Free>
std::optional<BlurredBar> fit_bar(const std::vector<double>& profile, double step_px,
                                  const BlurredBar& start) {
    static_assert(Free == 6 || Free == 4);
    constexpr int kParameters = 6;
    using Bar = Eigen::Matrix<double, kParameters, 1>;
    using Vector = Eigen::Matrix<double, Free, 1>;
    using Matrix = Eigen::Matrix<double, Free, Free>;
    static constexpr std::array<int, 6> kFree =
        Free == 6 ? std::array<int, 6>{0, 1, 2, 3, 4, 5} : std::array<int, 6>{0, 1, 3, 4, -1, -1};
    if (profile.size() < static_cast<std::size_t>(2 * kParameters) || !(step_px > 0) ||
        !(start.width_px > 0) || !(start.blur_sigma_px > 0))
        return std::nullopt;
    const double pivot = start.centre_px;
    const NormalTable& normal = normal_table();
    Bar q;
    q << (profile.front() + profile.back()) / 2, 0, start.contrast_dn, start.centre_px,
        start.width_px, start.blur_sigma_px;
    // The cost at a point with its normal equations: a step that is taken needs them next, so
    // they are made with the cost that decides it.
    const auto cost_and_normal = [&](const Bar& at, Matrix& jtj, Vector& jtr) {
        double cost = 0;
        jtj.setZero(), jtr.setZero();
        for (std::size_t i = 0; i < profile.size(); ++i) {
            const double x = static_cast<double>(i) * step_px;
            const double u1 = (x - at[3] + at[4] / 2) / at[5];
            const double u2 = (x - at[3] - at[4] / 2) / at[5];
            const NormalAt n1 = normal(u1), n2 = normal(u2);
            const double inside = n1.cdf - n2.cdf;
            const double r = profile[i] - (at[0] + at[1] * (x - pivot) + at[2] * inside);
            cost += r * r;
            const std::array<double, kParameters> all{1,
                                                      x - pivot,
                                                      inside,
                                                      at[2] * (n2.pdf - n1.pdf) / at[5],
                                                      at[2] * (n1.pdf + n2.pdf) / (2 * at[5]),
                                                      at[2] * (n2.pdf * u2 - n1.pdf * u1) / at[5]};
            std::array<double, Free> j{};
            for (std::size_t k = 0; k < Free; ++k) j[k] = all[static_cast<std::size_t>(kFree[k])];
            // The lower half only: the damped solve below (LDLT) reads no other.
            for (std::size_t a = 0; a < Free; ++a) {
                for (std::size_t b = 0; b <= a; ++b)
                    jtj(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) += j[a] * j[b];
                jtr[static_cast<Eigen::Index>(a)] += j[a] * r;
            }
        }
        return cost;
    };
    double lambda = 1e-3;
    Matrix jtj, trial_jtj;
    Vector jtr, trial_jtr;
    double cost = cost_and_normal(q, jtj, jtr);
    bool converged = false;
    for (int iteration = 0; iteration < 200 && !converged; ++iteration) {
        Matrix damped = jtj;
        damped.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
        const Vector step = damped.ldlt().solve(jtr);
        Bar trial = q;
        for (int k = 0; k < Free; ++k) trial[kFree[static_cast<std::size_t>(k)]] += step[k];
        trial[4] = std::max(trial[4], 0.05);
        trial[5] = std::max(trial[5], 0.05);
        const double trial_cost = cost_and_normal(trial, trial_jtj, trial_jtr);
        if (std::isfinite(trial_cost) && trial_cost <= cost) {
            converged = cost - trial_cost <= 1e-8 * (1 + cost) ||
                        step.cwiseAbs().maxCoeff() < 1e-7 * (1 + q.cwiseAbs().maxCoeff());
            q = trial;
            cost = trial_cost;
            jtj = trial_jtj, jtr = trial_jtr;
            lambda = std::max(lambda / 10, 1e-9);
        } else {
            lambda *= 10;
            converged = lambda > 1e9;  // no step lowers the cost: at the minimum
        }
    }
    if (!converged || !q.allFinite()) return std::nullopt;
    return BlurredBar{q[3], q[4], q[5], q[2]};
}

}  // namespace

std::optional<BlurredBar> fit_blurred_bar(const std::vector<double>& profile, double step_px,
                                          const BlurredBar& start, BarFit fit) {
    return fit == BarFit::contrast_and_blur_held ? fit_bar<4>(profile, step_px, start)
                                                 : fit_bar<6>(profile, step_px, start);
}

StrandHeight strand_height_from_width(double section_mm2, double width_mm, double width_sigma_mm) {
    if (!(section_mm2 > 0) || !(width_mm > 0))
        throw std::invalid_argument("a strand's height needs its cross-section and its width");
    const double bead_mm = std::sqrt(4 * section_mm2 / 3.14159265358979323846);
    if (width_mm * bead_mm <= section_mm2) return {bead_mm, kFreeBeadHeightSigmaMm, true};
    const double height = section_mm2 / width_mm;
    if (width_mm >= kScrapedFromShare * kNozzleFlatMm) return {height / 2, height / 2, false, true};
    return {height, height / width_mm * width_sigma_mm, false, false};
}

std::optional<StrandCrossing> strand_across(const GrayView& image, Point2 from, Point2 to,
                                            double px_per_mm, double strand_width_mm,
                                            const StrandRingLimits& limits) {
    const double span_px = std::hypot(to.x - from.x, to.y - from.y);
    if (!(span_px > 0) || !(px_per_mm > 0)) return std::nullopt;
    const Point2 unit{(to.x - from.x) / span_px, (to.y - from.y) / span_px};
    const auto falling = step_edge_on_segment(image, from, to, false, limits.edges);
    if (!falling) return std::nullopt;
    const auto inward = [&](double mm) {
        return Point2{falling->x - unit.x * mm * px_per_mm, falling->y - unit.y * mm * px_per_mm};
    };
    const auto rising = step_edge_on_segment(
        image, inward(limits.widest_multiple * strand_width_mm),
        inward(limits.narrowest_share * strand_width_mm / 2), true, limits.edges);
    if (!rising) return std::nullopt;
    const double width_px = (falling->x - rising->x) * unit.x + (falling->y - rising->y) * unit.y;
    const double width_mm = width_px / px_per_mm;
    if (width_mm < limits.narrowest_share * strand_width_mm ||
        width_mm > limits.widest_multiple * strand_width_mm)
        return std::nullopt;
    const Point2 middle{(rising->x + falling->x) / 2, (rising->y + falling->y) / 2};
    // The bed half a strand's width past its edge, against the strand's middle.
    const double past_px = strand_width_mm / 2 * px_per_mm;
    const auto middle_dn = grey_at(image, middle);
    const auto bed_dn =
        grey_at(image, {falling->x + unit.x * past_px, falling->y + unit.y * past_px});
    if (!middle_dn || !bed_dn || *middle_dn - *bed_dn < limits.min_contrast_dn) return std::nullopt;
    // The profile the width is fitted on: the strand and bare bed on either side of its edges.
    StrandCrossing crossing{
        middle, width_px, {}, limits.edges.sample_step_px * 2, 0, *middle_dn - *bed_dn};
    const double margin_px = limits.bar_fit_margin_mm * px_per_mm;
    crossing.middle_px = margin_px + width_px / 2;
    const Point2 first{rising->x - unit.x * margin_px, rising->y - unit.y * margin_px};
    const auto samples =
        static_cast<int>(std::floor((width_px + 2 * margin_px) / crossing.profile_step_px)) + 1;
    crossing.profile.reserve(static_cast<std::size_t>(samples));
    for (int k = 0; k < samples; ++k) {
        const double along = k * crossing.profile_step_px;
        const auto dn = grey_at(image, {first.x + unit.x * along, first.y + unit.y * along});
        if (!dn) return std::nullopt;
        crossing.profile.push_back(*dn);
    }
    return crossing;
}

std::optional<BlurredBar> strand_across_side(const std::vector<StrandCrossing>& crossings,
                                             const StrandRingLimits& limits, std::string& why_not) {
    // One fit of the side's profiles averaged about their middles: each profile alone, at a
    // camera's worst noise (6 grey levels on a strand 100 above the bed), leaves the blur and
    // the brightness to trade, and the median of such fits comes out a fifth low.
    if (crossings.size() < limits.min_profiles_per_side) {
        why_not = "the strand in " + std::to_string(crossings.size()) + " profiles (at least " +
                  std::to_string(limits.min_profiles_per_side) + " needed for its blur)";
        return std::nullopt;
    }
    const double step = crossings.front().profile_step_px;
    double before = std::numeric_limits<double>::max(), after = before, width = 0, contrast = 0;
    for (const auto& c : crossings) {
        before = std::min(before, c.middle_px);
        after = std::min(after, (static_cast<double>(c.profile.size()) - 1) * step - c.middle_px);
        width += c.width_px;
        contrast += c.contrast_dn;
    }
    const auto n = static_cast<double>(crossings.size());
    std::vector<double> mean;
    const auto samples = static_cast<int>(std::floor((before + after) / step)) + 1;
    mean.reserve(static_cast<std::size_t>(samples));
    for (int k = 0; k < samples; ++k) {
        const double x = -before + k * step;
        double sum = 0;
        for (const auto& c : crossings) {
            const double at = (c.middle_px + x) / step;
            const auto i = std::min(static_cast<std::size_t>(at), c.profile.size() - 2);
            const double f = at - static_cast<double>(i);
            sum += (1 - f) * c.profile[i] + f * c.profile[i + 1];
        }
        mean.push_back(sum / n);
    }
    const auto bar =
        fit_blurred_bar(mean, step, {before, width / n, limits.bar_start_blur_px, contrast / n});
    if (!bar || !(bar->blur_sigma_px > 0) || !(bar->contrast_dn > 0)) {
        why_not =
            "the blur across the strand could not be told from its width (their fit to its "
            "profiles did not settle)";
        return std::nullopt;
    }
    return bar;
}

namespace {

constexpr std::array<const char*, 4> kSideNames = {"top", "right", "bottom", "left"};

// Where one side's profiles stand: each one's share along the side (0 at its first corner, 1 at
// its second) and its two stations in pixels, from `outer_from_mm` to `outer_to_mm` across the
// side (outward positive), in one call through the lens. None near the corners or the seam.
struct SideStations {
    std::vector<double> t;
    std::vector<Point2> px;  // two a profile
};
SideStations side_stations(const MarkerFrame& frame, Point2 a, Point2 b, double outer_from_mm,
                           double outer_to_mm, const StrandRingLimits& limits) {
    const double length = std::hypot(b.x - a.x, b.y - a.y);
    const Point2 along{(b.x - a.x) / length, (b.y - a.y) / length};
    const Point2 outward{-along.y, along.x};  // the corners run clockwise as printed
    SideStations out;
    const double first_mm = limits.corner_clearance_share * length;
    const auto profiles =
        static_cast<int>(std::floor(((1 - limits.corner_clearance_share) * length - first_mm) /
                                    limits.profile_step_mm)) +
        1;
    for (int i = 0; i < profiles; ++i) {
        const double s = first_mm + i * limits.profile_step_mm;
        const double t = s / length;
        if (std::abs(t - 0.5) < limits.seam_clearance_share) continue;
        const Point2 p{a.x + s * along.x, a.y + s * along.y};
        out.t.push_back(t);
        for (const double d : {outer_from_mm, outer_to_mm})
            out.px.push_back(frame.to_fit_space({p.x + d * outward.x, p.y + d * outward.y}));
    }
    out.px = frame.to_pixels(out.px);
    return out;
}

// A side's strand widths, on the second pass: the bar's blur and contrast over the whole side,
// then each profile's width with them held; or, kept on the side, why they cannot be told.
void measure_side_widths(const std::vector<StrandCrossing>& crossings,
                         const StrandRingLimits& limits, SideProfiles& side) {
    std::string why_not;
    const auto bar = strand_across_side(crossings, limits, why_not);
    std::vector<double> widths;
    widths.reserve(crossings.size());
    for (const auto& c : crossings) widths.push_back(c.width_px);
    const double width = widths.empty() ? 0.0 : median_of(widths);
    if (bar && bar->blur_sigma_px > limits.widest_blur_share * width) {
        why_not = "the lens's blur across the strand (" + number_text("%.2f", bar->blur_sigma_px) +
                  " px) is over " + number_text("%.2f", limits.widest_blur_share) +
                  " of its width (" + number_text("%.2f", width) + " px)";
    }
    if (!why_not.empty()) {
        side.widths_unmeasured_because = why_not;
        return;
    }
    for (std::size_t i = 0; i < crossings.size(); ++i) {
        const auto& c = crossings[i];
        const auto held =
            fit_blurred_bar(c.profile, c.profile_step_px,
                            {c.middle_px, c.width_px, bar->blur_sigma_px, bar->contrast_dn},
                            BarFit::contrast_and_blur_held);
        if (!held) continue;
        side.width_t.push_back(side.t[i]);
        side.width_px.push_back(held->width_px);
    }
}

// One side on one pass: the strand crossed at every station, its centreline fitted (and on the
// second pass its widths); "" when it was, else why the ring is not measured.
std::string measure_side(const GrayView& image, const MarkerFrame& frame,
                         const SideStations& stations, std::size_t k, int pass,
                         double outer_span_mm, const StrandRingLayout& layout,
                         const StrandRingLimits& limits, SideProfiles& side, geometry::Line& line) {
    side = {};
    std::vector<Point2> centres_px;
    std::vector<StrandCrossing> crossings;
    for (std::size_t i = 0; i < stations.t.size(); ++i) {
        const Point2 from = stations.px[2 * i], to = stations.px[2 * i + 1];
        const double px_per_mm = std::hypot(to.x - from.x, to.y - from.y) / outer_span_mm;
        auto crossing = strand_across(image, from, to, px_per_mm, layout.strand_width_mm, limits);
        if (!crossing) continue;
        side.t.push_back(stations.t[i]);
        centres_px.push_back(crossing->centre_px);
        if (pass == 1) crossings.push_back(std::move(*crossing));
    }
    if (side.t.size() < limits.min_profiles_per_side)
        return std::string("its ") + kSideNames[k] + " side showed the strand in " +
               std::to_string(side.t.size()) + " of " + std::to_string(stations.t.size()) +
               " profiles (at least " + std::to_string(limits.min_profiles_per_side) + " needed)";
    side.centre = frame.from_pixels(centres_px);
    line = geometry::fit_line(side.centre);
    if (pass == 1) measure_side_widths(crossings, limits, side);
    return {};
}

// The ring's corners where its fitted sides meet (`corners_fit`, fit space), each with its
// uncertainty and the strand's width there, from the two sides that meet at it.
void ring_corners(const std::array<geometry::Line, 4>& lines,
                  const std::array<SideProfiles, 4>& sides, const std::vector<Point2>& corners_fit,
                  const MarkerFrame& frame, const StrandRingLimits& limits, StrandRing& ring) {
    const auto corners_px = frame.to_pixels(corners_fit);
    for (std::size_t k = 0; k < 4; ++k) {
        const std::size_t before = (k + 3) % 4;
        ring.corners_px[k] = corners_px[k];
        // A corner moves with either centreline's offset across it (the profiles are a few
        // pixels apart: each its own noise).
        const auto& a = lines[before];
        const auto& b = lines[k];
        const double sa = geometry::line_sigma_at(a, sides[before].centre, corners_fit[k]);
        const double sb = geometry::line_sigma_at(b, sides[k].centre, corners_fit[k]);
        const double sine = std::abs(a.direction.x * b.direction.y - a.direction.y * b.direction.x);
        ring.sigma_px[k] = frame.pixels_per_unit() * std::sqrt((sa * sa + sb * sb) / 2) / sine;
        // The side before ends at this corner, this side starts there.
        for (const std::size_t side : {before, k}) {
            if (sides[side].width_px.size() >= limits.min_profiles_per_side) continue;
            ring.width_unmeasured_because[k] =
                std::string("its ") + kSideNames[side] + " side: " +
                (sides[side].widths_unmeasured_because.empty()
                     ? "the strand's width fitted in " +
                           std::to_string(sides[side].width_px.size()) + " profiles"
                     : sides[side].widths_unmeasured_because);
        }
        if (!ring.width_unmeasured_because[k].empty()) continue;
        const auto end_of_before = linear_fit_at(sides[before].width_t, sides[before].width_px, 1);
        const auto start_of_this = linear_fit_at(sides[k].width_t, sides[k].width_px, 0);
        ring.width_px[k] = (end_of_before.value + start_of_this.value) / 2;
        ring.width_sigma_px[k] = std::sqrt(end_of_before.sigma * end_of_before.sigma +
                                           start_of_this.sigma * start_of_this.sigma) /
                                 2;
    }
}

}  // namespace

StrandRing measure_strand_ring(const GrayView& image,
                               const std::array<geometry::Point2, 4>& marker_corners_px,
                               const StrandRingLayout& layout, const geometry::CameraModel* camera,
                               const StrandRingLimits& limits) {
    StrandRing ring;
    const auto corners_laid = square_corners(layout.ring_half_mm);
    const double half_width = layout.strand_width_mm / 2;
    // The strand's outer edge (strand to bare bed, falling) is looked for from a little inside
    // its expected centreline to past its commanded outer edge; its inner edge (rising) on a
    // stretch ending just inside the outer edge found and reaching a widest strand's width
    // further in. Neither reaches the other's competitor (the quiet zone's fill inside, a
    // neighbour outside) however far a squashed strand spread.
    const double outer_from_mm = -limits.centre_uncertainty_mm;
    const double outer_to_mm = half_width + limits.reach_outside_mm;
    std::array<SideProfiles, 4> sides;
    std::array<geometry::Line, 4> lines;
    // The first pass expects the ring where the marker's corners put it (a marker's own edges
    // move with its strands' widths: tenths of a millimetre); the second where the first
    // found it.
    MarkerFrame frame(marker_corners_px, layout.marker_half_mm, camera);
    for (int pass = 0; pass < 2; ++pass) {
        if (pass == 1) {
            std::array<Point2, 4> found{};
            const auto met = where_sides_meet(lines);
            if (!met) {
                ring.unmeasured_because = "two of its sides fitted parallel";
                return ring;
            }
            const auto px = frame.to_pixels(*met);
            std::copy(px.begin(), px.end(), found.begin());
            frame = MarkerFrame(found, layout.ring_half_mm, camera);
        }
        for (std::size_t k = 0; k < 4; ++k) {
            const auto stations = side_stations(frame, corners_laid[k], corners_laid[(k + 1) % 4],
                                                outer_from_mm, outer_to_mm, limits);
            ring.unmeasured_because =
                measure_side(image, frame, stations, k, pass, outer_to_mm - outer_from_mm, layout,
                             limits, sides[k], lines[k]);
            if (!ring.unmeasured_because.empty()) return ring;
        }
    }
    const auto met = where_sides_meet(lines);
    if (!met) {
        ring.unmeasured_because = "two of its sides fitted parallel";
        return ring;
    }
    ring_corners(lines, sides, *met, frame, limits, ring);
    return ring;
}

}  // namespace calbox::vision
