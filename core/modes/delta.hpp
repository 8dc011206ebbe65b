#pragma once
// The delta mode's measure step: photos of the printed delta target -> each marker corner's
// position on the bed, paired with where the target commanded it.
#include <array>
#include <optional>
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

// One of the classic bars, measured edge to edge along its length as a vernier reads it (the
// jaws square to the bar, touching its end faces where they reach furthest).
struct BarLengthMeasurement {
    char tower = 'A';
    double commanded_start_mm = 0, commanded_end_mm = 0;  // distances from the bed centre
    double commanded_mm = 0;                              // end minus start
    double measured_mm = 0;
    double sigma_mm = 0;
    double surface_height_mm = 0;  // mean of the ends' printed heights the edges were mapped at
    // The middles of the near and far end faces in the first photo, on the bed frame at the
    // height they were mapped at: where to draw the bar on that photo.
    std::array<geometry::Point3, 2> faces_seen_mm{};
};

struct DeltaMeasurement {
    targets::DeltaTarget target;
    std::vector<solve::FeatureMeasurement> features;          // one per marker corner seen
    std::vector<BarLengthMeasurement> bars;                   // those fully seen in every photo
    std::vector<std::vector<vision::DetectedMarker>> frames;  // what each photo showed
    double bed_scale = 1;  // the print in the photos against as printed (the bed's expansion)
    // Corners and bar ends moved along their rays to the surface heights a fit of the corners
    // gives (the fit's parallax terms then have nothing left to do); else at the nominal height.
    bool heights_from_fit = false;
};

// A corner's feature id: "m" marker id "c" corner index (OpenCV's order).
std::string corner_feature_id(int marker_id, int corner);

// Throws MeasureError with one line for a photo that cannot be measured: over- or
// under-exposed (its bright part clipped), no markers, markers that are not this target's or
// not laid out as it lays them (a photo of another target), or under three quarters of the
// target's markers in view. Positions are given as printed: when the photos were taken with the bed
// at `photo_bed_temperature_c` rather than the machine's bed_temperature_c, the bed's expansion
// (bed_material) is taken out.
DeltaMeasurement measure_delta(const models::MachineFile& machine,
                               const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               const std::vector<vision::GrayView>& frames,
                               std::optional<double> photo_bed_temperature_c = {});

}  // namespace calbox::modes
