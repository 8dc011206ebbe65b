#include "firmware/cycle/photos.hpp"

#include <stdexcept>

namespace calbox::firmware {

vision::GrayView view_of(const hal::Frame& f) {
    return {f.pixels.data(), f.width_px, f.height_px, f.stride_bytes};
}

vision::GrayView calibrated_view_of(const hal::Frame& frame, const geometry::CameraModel& camera) {
    if (const auto size = geometry::photo_size_mismatch(camera, frame.width_px, frame.height_px);
        !size.empty())
        throw std::runtime_error("the photo is " + size + " (camera.yaml)");
    return view_of(frame);
}

CalibratedPhotos calibrated_photos(const MeasureInput& input) {
    CalibratedPhotos p{geometry::camera_from_yaml(input.camera_yaml),
                       geometry::plane_from_yaml(input.plane_yaml),
                       {},
                       {}};
    for (const auto& frame : *input.frames) {
        p.views.push_back(calibrated_view_of(frame, p.camera));
        p.names.push_back("frame " + std::to_string(p.names.size() + 1));
    }
    return p;
}

}  // namespace calbox::firmware

namespace calbox::firmware {

void measure_photos(CycleSteps& steps, MeasureInput input, Measurer measurer,
                    std::function<void()> then) {
    auto overlay = std::make_shared<std::string>();
    const std::string overlay_name = input.overlay_name;
    auto take = std::make_shared<TakeMeasurement>();
    steps.work([measurer = std::move(measurer), input = std::move(input), overlay,
                take] { *take = measurer(calibrated_photos(input), *overlay); },
               [&steps, overlay, take, overlay_name, then = std::move(then)] {
                   if (!steps.keep(overlay_name, *overlay)) return;
                   (*take)();
                   then();
               });
}

}  // namespace calbox::firmware
