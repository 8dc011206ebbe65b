#pragma once
// The delta mode's measure step: photos of the printed delta target -> each marker corner's
// position on the bed, paired with where the target commanded it.
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/solve/delta_fit.hpp"
#include "core/targets/delta_target.hpp"
#include "core/vision/markers.hpp"

namespace calbox::modes {

class MeasureError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct DeltaMeasurement {
    targets::DeltaTarget target;
    std::vector<solve::FeatureMeasurement> features;          // one per marker corner seen
    std::vector<std::vector<vision::DetectedMarker>> frames;  // what each photo showed
};

// Throws MeasureError with one line for a photo that cannot be measured: over- or
// under-exposed, no markers, markers that are not this target's, or less than half of the
// target in view.
DeltaMeasurement measure_delta(const models::MachineFile& machine,
                               const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               const std::vector<vision::GrayView>& frames);

}  // namespace calbox::modes
