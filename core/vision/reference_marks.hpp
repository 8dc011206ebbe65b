#pragma once
// Fixed reference marks: a few markers stuck on the machine's frame or bed, outside the work
// area, that nothing the machine makes covers. Their view is stored when the bed plane is taken;
// at the start of each cycle they are found again, and if they seem to have moved on the bed the
// camera has moved (a knock, a loosened mount) and the stored plane no longer holds.
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/vision/markers.hpp"

namespace calbox::vision {

struct ReferenceView {
    std::string dictionary;
    std::vector<DetectedMarker> marks;  // by id, corners refined
};

// The marks of `dictionary` in the photo, corners refined through the camera's model.
ReferenceView find_reference_marks(const GrayView& image, const std::string& dictionary,
                                   const geometry::CameraModel& camera);

// The stored marks found again: each looked for first in a window around where it was stored
// (grown by its own side, so that a knocked camera still shows it there), and the whole photo
// searched as find_reference_marks does only when one is not in its window.
ReferenceView find_reference_marks_again(const GrayView& image, const ReferenceView& stored,
                                         const geometry::CameraModel& camera);

std::string reference_to_yaml(const ReferenceView& view);
ReferenceView reference_from_yaml(const std::string& text);  // throws geometry::FileFormatError

// How far the stored marks seem to have moved on the bed, both views' corners mapped onto the
// bed through the stored camera and plane.
struct CameraMove {
    int marks_compared = 0;
    std::vector<int> missing;  // stored marks not found now, by id
    double largest_mm = 0;     // the largest corner's apparent move
    double rms_mm = 0;         // over the compared corners
};

CameraMove compare_reference(const ReferenceView& stored, const ReferenceView& now,
                             const geometry::CameraModel& camera, const geometry::BedPlane& plane);

}  // namespace calbox::vision
