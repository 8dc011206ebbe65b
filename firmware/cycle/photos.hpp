#pragma once
// The photos a mode measures, as the box took them: checked against the size the camera was
// calibrated at, named for the records ("frame 1"), with the set-up they are measured with.
#include <functional>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/image_view.hpp"
#include "firmware/cycle/cycle_mode.hpp"

namespace calbox::firmware {

vision::GrayView view_of(const hal::Frame& frame);
// Photos from files or another camera: the lens model holds only at the size it was calibrated
// at; throws std::runtime_error naming both sizes.
vision::GrayView calibrated_view_of(const hal::Frame& frame, const geometry::CameraModel& camera);

struct CalibratedPhotos {
    geometry::CameraModel camera;
    geometry::BedPlane plane;
    std::vector<vision::GrayView> views;  // into the input's frames: keep it alive
    std::vector<std::string> names;       // "frame 1", ...
};
// Off the loop: throws when the set-up's files do not read or a photo is of another size.
CalibratedPhotos calibrated_photos(const MeasureInput& input);

}  // namespace calbox::firmware

namespace calbox::firmware {

// A mode's measuring, split at the loop's edge: run off the loop on the photos (writing the
// overlay's PNG), it returns what stores the measurement in the mode, run on the loop.
using TakeMeasurement = std::function<void()>;
using Measurer = std::function<TakeMeasurement(const CalibratedPhotos&, std::string& overlay_png)>;
// Measures the photos with `measurer`, keeps the overlay as input.overlay_name in the data
// directory, stores the measurement, then `then`.
void measure_photos(CycleSteps& steps, MeasureInput input, Measurer measurer,
                    std::function<void()> then);

}  // namespace calbox::firmware
