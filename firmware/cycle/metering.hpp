#pragma once
// The box's own exposure before each capture of the work: a frame at the exposure the camera
// last took, read over the work area; read again at half the exposure while its bright side is
// clipped; then one exposure that holds both its sides, or two (bracketed) merged where one
// cannot. What was read, chosen and captured is kept for the cycle's record.
#include <chrono>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/vision/exposure.hpp"
#include "hal/camera.hpp"

namespace calbox::firmware {

// One capture's exposure, as the cycle's record keeps it.
struct CaptureExposure {
    std::string what;  // "target", "pass-2-verify"
    struct Reading {
        std::chrono::microseconds exposure{0};
        double analogue_gain = 1;
        vision::WorkAreaLight light;
    };
    std::vector<Reading> readings;                // the metering frames, in order
    std::chrono::microseconds exposure{0};        // the capture's (a bracket's long one)
    std::chrono::microseconds short_exposure{0};  // a bracket's short one, else 0
    double clipped_before = 0;                    // of the work area, in the first metering frame
    double clipped_after = 0;  // in the first frame measured (merged for a bracket)
    double from_short_share = 0;
    std::string why;  // the plan's line, or why there was none
};
void to_json(nlohmann::json& j, const CaptureExposure& e);

class MeteredCapture {
  public:
    // `mark_centres_px`: the stored reference marks' centres (the work area lies inside them).
    // `start`: the first metering frame's exposure and gain (the last capture's); unset, the
    // camera's own.
    MeteredCapture(std::string what, int frames, std::vector<geometry::Point2> mark_centres_px,
                   hal::CaptureRequest start = {}, vision::MeteringLimits limits = {});

    hal::CaptureRequest first() const { return start_; }
    // Reads a metering frame: the next metering request, or none once the plan is made.
    std::optional<hal::CaptureRequest> read(const hal::Frame& frame);
    // The captures the plan calls for: one, or a bracket's long then short; none when the last
    // metering frame is held as it is (a single frame wanted).
    std::vector<hal::CaptureRequest> captures() const;
    // The frames measured: each capture's frames, merged pairwise for a bracket.
    std::vector<hal::Frame> finish(std::vector<std::vector<hal::Frame>> shots);

    const CaptureExposure& record() const { return record_; }
    // Where the next capture's metering starts: this one's exposure (a bracket's long one).
    hal::CaptureRequest next_start() const;
    std::string summary() const;  // one line for the log

  private:
    vision::WorkAreaLight meter(const hal::Frame& frame) const;

    int frames_;
    std::vector<geometry::Point2> mark_centres_px_;
    hal::CaptureRequest start_;
    std::optional<hal::Frame> held_;  // the last metering frame, when it is the capture
    vision::MeteringLimits limits_;
    CaptureExposure record_;
    vision::ExposurePlan plan_;
    bool planned_ = false;
};

}  // namespace calbox::firmware
