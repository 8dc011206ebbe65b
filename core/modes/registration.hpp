#pragma once
// Print and cut: a drawing printed on the stock with three or four registration marks (filled
// circles at known places in the drawing) found in the photo, and the drawing's place on the
// machine fitted from them (turn and shift; the scale too where four are given), each mark's
// residual reported and a fit past the limit refused.
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/image_view.hpp"
#include "core/modes/planar.hpp"

namespace calbox::modes {

class RegistrationError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Filled dark circles (as vinyl cutters and LightBurn print them), dark crosses (a plus of two
// bars, as print shops' registration marks), or ArUco/AprilTag markers, each told by its id: no
// layout is ambiguous then.
enum class MarkKind { circles, crosses, markers };

struct RegistrationRequest {
    std::vector<geometry::Point2> marks_drawing_mm;  // three or four, in the drawing's frame
    MarkKind kind = MarkKind::circles;
    // Markers: each mark's id (as marks_drawing_mm, its centre there) and their dictionary.
    std::vector<int> marker_ids;
    std::string dictionary = "DICT_4X4_50";
    double mark_diameter_mm = 5;   // circles: the diameter; crosses: tip to tip; markers: the side
    double cross_line_mm = 0.5;    // crosses: each bar's width
    double surface_height_mm = 0;  // the printed sheet's top above the bed
    // A mark this far from where the fit puts it is a misprint, a smudge or another mark: the
    // drawing cannot be placed to the goal (0.1 mm) through it.
    double max_residual_mm = 0.1;
};

struct RegisteredMark {
    geometry::Point2 drawing_mm, machine_mm;
    double residual_mm = 0;  // from where the fit puts the drawing's mark
    double sigma_mm = 0;     // the centre's standard uncertainty in each coordinate (the photo)
};

// The drawing's place: machine = origin + scale R(rotation) drawing.
struct Registration {
    std::vector<RegisteredMark> marks;
    geometry::Point2 origin_mm;  // where the drawing's (0, 0) lies on the machine
    double rotation_deg = 0;
    double scale = 1;
    bool scale_fitted = false;  // four marks: the printer's stretch is fitted, else held at 1
    double worst_residual_mm = 0;
    double surface_height_mm = 0;
};

// Throws RegistrationError (one line with the figure) when the marks are not three or four, are
// not all found, lie symmetrically (the drawing could be placed two ways), or a residual passes
// the limit; BedViewError for a result that does not say where the bed lies or a photo of
// another size than the camera's.
Registration register_marks(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                            const vision::GrayView& photo, const PlanarSolution& solution,
                            const RegistrationRequest& request, const std::string& source);

// `calbox.registration/1`, with the result's machine fingerprint. Reading throws RecordError
// naming `source`.
std::string registration_to_json(const Registration& r, const std::string& machine_fingerprint);
struct RegistrationRecord {
    Registration registration;
    std::string machine_fingerprint;
};
RegistrationRecord registration_from_json(const std::string& text, const std::string& source);

}  // namespace calbox::modes
