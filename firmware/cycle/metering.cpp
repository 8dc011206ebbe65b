#include "firmware/cycle/metering.hpp"

#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <utility>

#include "core/number_text.hpp"
#include "firmware/cycle/photos.hpp"

namespace calbox::firmware {
namespace {

// Read again at half the exposure at most this many times: a sixteenth of the first reading's
// light, past which a clipped bright side is the lamp itself, not a surface.
constexpr std::size_t kMostReadings = 5;

std::chrono::microseconds scaled(std::chrono::microseconds exposure, double ratio) {
    return std::chrono::microseconds(
        std::max<std::int64_t>(1, std::llround(static_cast<double>(exposure.count()) * ratio)));
}

}  // namespace

void to_json(nlohmann::json& j, const CaptureExposure& e) {
    nlohmann::json readings = nlohmann::json::array();
    for (const auto& r : e.readings)
        readings.push_back({{"exposure_us", r.exposure.count()},
                            {"analogue_gain", r.analogue_gain},
                            {"bright_dn", r.light.bright_dn},
                            {"dark_dn", r.light.dark_dn},
                            {"clipped_share", r.light.clipped_share}});
    j = {{"what", e.what},
         {"readings", readings},
         {"exposure_us", e.exposure.count()},
         {"bracketed", e.short_exposure.count() > 0},
         {"short_exposure_us", e.short_exposure.count()},
         {"work_area_clipped_before", e.clipped_before},
         {"work_area_clipped_after", e.clipped_after},
         {"from_short_share", e.from_short_share},
         {"why", e.why}};
}

MeteredCapture::MeteredCapture(std::string what, int frames,
                               std::vector<geometry::Point2> mark_centres_px,
                               hal::CaptureRequest start, vision::MeteringLimits limits)
    : frames_(frames),
      mark_centres_px_(std::move(mark_centres_px)),
      start_(start),
      limits_(limits) {
    start_.frame_count = 1;
    record_.what = std::move(what);
}

hal::CaptureRequest MeteredCapture::next_start() const {
    // A bracket's long exposure: the next reading then sees the hot spot clipped again and is
    // cut for it, as this one was, rather than taking the short one for the whole scene.
    const auto exposure = record_.exposure;
    if (exposure.count() <= 0) return {};
    return {1, exposure, record_.readings.empty() ? 1.0 : record_.readings.back().analogue_gain};
}

vision::WorkAreaLight MeteredCapture::meter(const hal::Frame& frame) const {
    try {
        return vision::meter_work_area(
            view_of(frame),
            vision::work_area_inside(mark_centres_px_, frame.width_px, frame.height_px), limits_);
    } catch (const std::invalid_argument&) {
        // Marks in a line, or off this frame (photos of another size): the frame less its
        // border, as without marks.
        return vision::meter_work_area(
            view_of(frame), vision::work_area_inside({}, frame.width_px, frame.height_px), limits_);
    }
}

std::optional<hal::CaptureRequest> MeteredCapture::read(const hal::Frame& frame) {
    const auto light = meter(frame);
    record_.readings.push_back({frame.metadata.exposure, frame.metadata.analogue_gain, light});
    if (record_.readings.size() == 1) record_.clipped_before = light.clipped_share;
    if (frame.metadata.exposure.count() <= 0) {
        // Photos from files, or a camera that keeps its exposure to itself: nothing to scale
        // from; a single frame wanted is this one.
        planned_ = true;
        record_.why = "the camera does not report its exposure: taken at its own";
        if (frames_ == 1) held_ = frame;
        return std::nullopt;
    }
    plan_ = vision::plan_exposure(light, limits_,
                                  frame.metadata.exposure < record_.readings.front().exposure);
    record_.why = plan_.why;
    if (plan_.step == vision::ExposurePlan::Step::meter_again) {
        if (record_.readings.size() < kMostReadings)
            return hal::CaptureRequest{1, scaled(frame.metadata.exposure, plan_.ratio),
                                       frame.metadata.analogue_gain};
        // Still clipped at a sixteenth: the brightest exposure tried is kept and said.
        plan_.step = vision::ExposurePlan::Step::single;
        plan_.ratio = 1;
        record_.why += " (still clipped after " + std::to_string(kMostReadings) +
                       " readings: captured at the last)";
    }
    planned_ = true;
    if (plan_.step == vision::ExposurePlan::Step::single && plan_.ratio == 1 && frames_ == 1)
        held_ = frame;
    return std::nullopt;
}

std::vector<hal::CaptureRequest> MeteredCapture::captures() const {
    if (!planned_) throw std::logic_error("captures asked before the metering is done");
    if (held_) return {};
    // A camera that does not say its exposure: its own.
    if (record_.readings.back().exposure.count() <= 0) return {{frames_, {}, {}}};
    const auto& last = record_.readings.back();
    std::vector<hal::CaptureRequest> out{
        {frames_, scaled(last.exposure, plan_.ratio), last.analogue_gain}};
    if (plan_.step == vision::ExposurePlan::Step::bracket)
        out.push_back({frames_, scaled(last.exposure, plan_.short_ratio), last.analogue_gain});
    return out;
}

std::vector<hal::Frame> MeteredCapture::finish(std::vector<std::vector<hal::Frame>> shots) {
    if (held_) shots = {{std::move(*held_)}}, held_.reset();
    if (shots.empty() || shots.front().empty())
        throw std::invalid_argument("a metered capture needs its frames");
    std::vector<hal::Frame> out;
    record_.exposure = shots.front().front().metadata.exposure;
    if (shots.size() == 1) {
        out = std::move(shots.front());
    } else {
        const auto& longs = shots[0];
        const auto& shorts = shots[1];
        if (longs.size() != shorts.size())
            throw std::invalid_argument("a bracket's two captures differ in frames");
        record_.short_exposure = shorts.front().metadata.exposure;
        double from_short = 0;
        for (std::size_t i = 0; i < longs.size(); ++i) {
            const double ratio = static_cast<double>(longs[i].metadata.exposure.count()) /
                                 static_cast<double>(shorts[i].metadata.exposure.count());
            auto merged =
                vision::merge_bracket(view_of(longs[i]), view_of(shorts[i]), ratio, limits_);
            from_short += merged.from_short_share;
            hal::Frame frame;
            frame.width_px = merged.width_px;
            frame.height_px = merged.height_px;
            frame.stride_bytes = merged.width_px;
            frame.format = hal::PixelFormat::gray8;
            frame.pixels = std::move(merged.pixels);
            frame.metadata = shorts[i].metadata;  // on the short exposure's scale
            out.push_back(std::move(frame));
        }
        record_.from_short_share = from_short / static_cast<double>(longs.size());
    }
    record_.clipped_after = meter(out.front()).clipped_share;
    return out;
}

std::string MeteredCapture::summary() const {
    std::string line =
        record_.what + ": exposure " +
        (record_.exposure.count() > 0 ? std::to_string(record_.exposure.count()) + " us"
                                      : std::string("the camera's own"));
    if (record_.short_exposure.count() > 0)
        line += " and " + std::to_string(record_.short_exposure.count()) + " us, merged (" +
                number_text("%.1f", 100 * record_.from_short_share) + " % from the short one)";
    line += "; the work area " + number_text("%.1f", 100 * record_.clipped_before) +
            " % clipped before, " + number_text("%.1f", 100 * record_.clipped_after) +
            " % after; " + record_.why;
    return line;
}

}  // namespace calbox::firmware
