// The cycle's photos (firmware/cycle/cycle.hpp): frames captured under the lamp, metered to
// an exposure first where the settings ask it, and the live preview between cycles.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/geometry/calibration.hpp"
#include "core/number_text.hpp"
#include "core/vision/reference_marks.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/cycle/metering.hpp"

namespace calbox::firmware {

void Cycle::capture(int frames, std::function<void(std::vector<hal::Frame>)> then) {
    shoot({frames, {}, {}}, std::move(then));
}

void Cycle::shoot(const hal::CaptureRequest& request,
                  std::function<void(std::vector<hal::Frame>)> then) {
    const unsigned generation = generation_;
    d_.lines.set_light(true);
    phase_started_ = d_.clock.now();
    if (previewing_) {
        capture_after_preview_ = request;
    } else {
        d_.camera.start_capture(request);
    }
    // on_camera() continues; the continuation checks the generation.
    pending_capture_ = [this, generation, then = std::move(then)](std::vector<hal::Frame> f) {
        if (current(generation)) then(std::move(f));
    };
}

struct Cycle::MeteredRun {
    MeteredCapture metering;
    std::vector<std::vector<hal::Frame>> shots;  // each planned capture's frames, in order
    std::function<void(std::vector<hal::Frame>)> then;
};

void Cycle::capture_metered(const std::string& what, int frames,
                            std::function<void(std::vector<hal::Frame>)> then) {
    // The work area lies inside the stored reference marks (a box without them: the frame less
    // its border).
    std::vector<geometry::Point2> mark_centres;
    if (const auto stored = read(kReferenceFile)) {
        try {
            for (const auto& m : vision::reference_from_yaml(*stored).marks) {
                geometry::Point2 c{0, 0};
                for (const auto& p : m.corners) c.x += p.x / 4, c.y += p.y / 4;
                mark_centres.push_back(c);
            }
        } catch (const geometry::FileFormatError&) {
            mark_centres.clear();  // the cycle's camera check has already refused a broken file
        }
    }
    auto run = std::make_shared<MeteredRun>(
        MeteredRun{MeteredCapture(what, frames, std::move(mark_centres), metering_start_),
                   {},
                   std::move(then)});
    shoot(run->metering.first(),
          [this, run](std::vector<hal::Frame> f) { metered_reading(run, std::move(f)); });
}

void Cycle::metered_reading(const std::shared_ptr<MeteredRun>& run, std::vector<hal::Frame> f) {
    std::optional<hal::CaptureRequest> again;
    try {
        if (f.empty()) throw std::runtime_error("the camera gave no frame");
        again = run->metering.read(f.front());
    } catch (const std::exception& e) {
        fail(std::string("metering: ") + e.what());
        return;
    }
    if (again) {
        shoot(*again,
              [this, run](std::vector<hal::Frame> next) { metered_reading(run, std::move(next)); });
        return;
    }
    metered_capture(run);
}

void Cycle::metered_capture(const std::shared_ptr<MeteredRun>& run) {
    const auto planned = run->metering.captures();
    if (run->shots.size() < planned.size()) {
        shoot(planned[run->shots.size()], [this, run](std::vector<hal::Frame> f) {
            run->shots.push_back(std::move(f));
            metered_capture(run);
        });
        return;
    }
    std::vector<hal::Frame> frames;
    try {
        frames = run->metering.finish(std::move(run->shots));
    } catch (const std::exception& e) {
        fail(std::string("capture: ") + e.what());
        return;
    }
    log(run->metering.summary());
    exposures_.push_back(run->metering.record());
    metering_start_ = run->metering.next_start();
    if (!keep(record_name("exposure.json"), nlohmann::json(exposures_).dump(1) + "\n")) return;
    run->then(std::move(frames));
}

bool Cycle::preview() {
    if (previewing_ || pending_capture_ || d_.worker.busy()) return false;
    d_.camera.start_capture({1, {}, {}});
    previewing_ = true;
    return true;
}

void Cycle::on_camera() {
    hal::CaptureResult result = d_.camera.take_frames();
    if (previewing_) {
        previewing_ = false;
        if (capture_after_preview_) {
            d_.camera.start_capture(*capture_after_preview_);
            capture_after_preview_.reset();
        }
        if (!result.ok()) {
            log("live view: " + result.error, hal::LogLevel::warning);
        } else if (!result.frames.empty()) {
            tell(&CycleNews::frame, result.frames.front());
        }
        return;
    }
    if (result.ok() && !result.frames.empty()) tell(&CycleNews::frame, result.frames.front());
    report_.camera_seconds +=
        std::chrono::duration<double>(d_.clock.now() - phase_started_).count();
    d_.lines.set_light(false);
    auto then = std::move(pending_capture_);
    pending_capture_ = nullptr;
    if (!then) return;  // a capture the cycle no longer waits for
    if (!result.ok()) {
        if (state_ != CycleState::idle && state_ != CycleState::error) fail(result.error);
        return;
    }
    then(std::move(result.frames));
}

}  // namespace calbox::firmware
