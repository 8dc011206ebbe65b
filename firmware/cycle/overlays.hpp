#pragma once
// What measure found, drawn on its first photo: `calbox measure --overlay` and each cycle's record
// (cycle-NNNN-overlay.png). PNG bytes, so that OpenCV stays out of this header.
#include <string>

#include "core/geometry/calibration.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/delta.hpp"
#include "core/modes/galvo.hpp"
#include "core/modes/planar.hpp"
#include "core/vision/image_view.hpp"

namespace calbox::firmware {

// Each marker's outline, each corner's placement error as an arrow (magnified, with its factor
// printed) and each bar between its measured end ticks with its length.
std::string delta_overlay_png(const vision::GrayView& photo,
                              const modes::DeltaMeasurement& measured,
                              const geometry::CameraModel& camera, const geometry::BedPlane& plane);
// Each mark measured (green; every fifth labelled column,row) and each extra blob (orange).
std::string galvo_overlay_png(const vision::GrayView& photo,
                              const modes::GalvoMeasurement& measured,
                              const models::MachineFile& machine,
                              const geometry::CameraModel& camera, const geometry::BedPlane& plane);
// Each hole used (green; the fiducials labelled) and each extra blob (orange).
std::string planar_overlay_png(const vision::GrayView& photo,
                               const modes::PlanarMeasurement& measured,
                               const models::MachineFile& machine,
                               const geometry::CameraModel& camera,
                               const geometry::BedPlane& plane);

// The error field on a plain map of the machine's frame (x right, y up): each point's error as
// an arrow, magnified by a round factor that makes the largest about a twelfth of the map, with
// the factor, the largest error and a scale bar printed. Each cycle's record
// (cycle-NNNN-error-field.png), for the page. Throws std::invalid_argument without a point.
struct FieldArrow {
    geometry::Point2 at_mm, error_mm;
};
std::string error_field_png(const std::vector<FieldArrow>& arrows, const std::string& title);

}  // namespace calbox::firmware
