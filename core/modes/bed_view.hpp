#pragma once
// The bed as the machine sees it: a photo from the box's camera projected through its model and
// the bed plane onto the machine's coordinates (as a job compensated through the planar result
// in force means them), at a stated scale, with the machine's travel, the measured area and its
// axes drawn over it; and the world file that tells other programs where its pixels are.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/image_view.hpp"
#include "core/modes/planar.hpp"
#include "core/vision/image_codec.hpp"

namespace calbox::modes {

class BedViewError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Where the camera's bed lies in the machine's coordinates: a point of the plane's bed frame and
// the machine position that a job aimed there through the planar correction lands on. The
// placement the solve fitted (the machine's frame in the camera's), the rigid part the
// correction leaves to the work's zero and heading, and the work zero the target ran at, in one
// rigid map (mirrored first where the bed frame is).
struct BedToMachine {
    bool mirrored = false;
    double rotation_rad = 0;
    geometry::Point2 translation_mm;
    geometry::Point2 machine_of(geometry::Point2 bed_mm) const;
    geometry::Point2 bed_of(geometry::Point2 machine_mm) const;
};

// Throws BedViewError naming `source` for a result that does not say where the bed lies (one
// written before calbox recorded its frame or its bed's handedness).
BedToMachine planar_bed_to_machine(const PlanarSolution& solution, const std::string& source);

// The same for a photo to be read onto the machine: throws BedViewError for a photo of another
// size than the camera's too.
BedToMachine photo_on_machine(const geometry::CameraModel& camera, const vision::GrayView& photo,
                              const PlanarSolution& solution, const std::string& source);

// The photo's own scale at a point of the bed: pixels a millimetre, the mean over the two steps
// from `at` to `x_step` and `y_step` (each a millimetre away on the bed), through the lens.
double photo_px_per_mm(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                       const geometry::Point3& at, const geometry::Point3& x_step,
                       const geometry::Point3& y_step);

struct BedViewRequest {
    // The machine coordinates shown; all four 0: the machine's travel.
    double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
    // 0: the camera's own scale at the middle of the area, rounded up to 0.01 mm.
    double mm_per_px = 0;
    // The height of what is seen above the bed the plane was taken on (the stock's top).
    double surface_height_mm = 0;
    // A view coarser than the photo averages several samples a pixel, so that the photo's detail
    // does not alias into it; a picture only for the eye (the cycle's record) may take one.
    bool average_samples = true;
};

// The view: north up, pixel (0, 0)'s centre at machine (min_x + s/2, max_y - s/2).
struct BedView {
    vision::GrayPixels pixels;  // 0 where the camera does not see
    vision::GrayPixels seen;    // 255 where it does, 0 elsewhere
    double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
    double mm_per_px = 0;
    double surface_height_mm = 0;
    double camera_mm_per_px = 0;  // the photo's own scale at the view's middle
    double seen_share = 0;        // of the view's pixels that the photo covers
    // Two standard deviations of a point's position in each coordinate: the camera model's and
    // the plane's reprojection (at the photo's scale) and what the planar model leaves.
    double accuracy_mm = 0;

    geometry::Point2 machine_of_pixel(double column, double row) const;
    geometry::Point2 pixel_of_machine(geometry::Point2 machine_mm) const;
};

// Throws BedViewError (one line: the figure that decided) for a photo of another size than the
// camera's, an area outside the machine's travel or of no size, a view over 40 megapixels, a
// scale finer than a tenth of the photo's, or an area the camera does not see at all.
BedView render_bed_view(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                        const vision::GrayView& photo, const PlanarSolution& solution,
                        const BedViewRequest& request, const std::string& source);

// The view in colour with the machine's travel (blue), the area the result was measured over
// (green), the machine's X and Y axes from its zero (red arrows, where they fall in the view), and
// a line stating scale, height and accuracy. Rows packed, three bytes a pixel (blue, green, red).
std::vector<std::uint8_t> bed_view_with_overlay(const BedView& view,
                                                const PlanarSolution& solution);

// An ESRI world file (.pgw beside a PNG): x and y size of a pixel, the rotation terms, and the
// centre of the top-left pixel, in machine millimetres.
std::string world_file_text(const BedView& view);

}  // namespace calbox::modes
