#pragma once
// Intrinsic calibration from board images, and the bed plane from one board lying on the bed.
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/camera_model.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "core/vision/image_view.hpp"

namespace calbox::geometry {

class CalibrationError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Board corners found in one image, with their positions on the board (OpenCV's board frame).
struct BoardObservation {
    std::vector<Point2> image_points;
    std::vector<Point3> object_points;
    std::vector<int> ids;  // chessboard: corner index; ChArUco: corner id
};

// Empty when the board is not in the image. Chessboards through findChessboardCornersSB,
// ChArUco boards through marker detection and corner interpolation (at least 6 corners), dot
// grids through findCirclesGrid (dark dots on light, or light on dark). Throws
// CalibrationError for an ArUco grid, which has no board corners.
std::optional<BoardObservation> find_board(const PatternSpec& pattern,
                                           const vision::GrayView& image);

struct NamedImage {
    std::string name;
    vision::GrayView image;
};

struct ViewReport {
    std::string name;
    int points = 0;
    double rms_px = 0;
};

struct CalibrationResult {
    CameraModel camera;
    std::vector<ViewReport> views;     // used views with their reprojection RMS
    std::vector<std::string> skipped;  // images where the board was not found
};

constexpr int kMinimumCalibrationViews = 6;

struct ObservedView {
    std::string name;
    BoardObservation board;
};

// The solve alone, from boards already found (the box finds each view's board as it is taken,
// to say at once whether it counts); the same errors as calibrate_camera.
CalibrationResult calibrate_from_views(LensModel model, const std::vector<ObservedView>& views,
                                       int width_px, int height_px);

// How much of the image the views' corners cover: the share of an 8 x 6 grid of cells holding
// at least one corner. A calibration whose corners all sit in the middle extrapolates the
// lens's distortion to the edges, where the bed's far corners are.
double image_coverage(const std::vector<ObservedView>& views, int width_px, int height_px);

// Throws CalibrationError when fewer than kMinimumCalibrationViews views are usable (naming how
// many were found), when images differ in size, or when OpenCV's solver fails.
CalibrationResult calibrate_camera(const PatternSpec& pattern, LensModel model,
                                   const std::vector<NamedImage>& images);

// The bed frame: right-handed, z up out of the bed, origin under the board's first inner corner,
// x along the board's columns; OpenCV's board frame (z into the board) turned over about x.
struct BedPlane {
    RigidPose bed_to_camera;
    double board_thickness_mm = 0;
    double rms_px = 0;
};

// Throws CalibrationError when the board is not found.
BedPlane estimate_bed_plane(const CameraModel& camera, const PatternSpec& pattern,
                            const vision::GrayView& image, double board_thickness_mm);

std::string plane_to_yaml(const BedPlane& plane);
BedPlane plane_from_yaml(const std::string& text);  // throws FileFormatError

// Raw pixels -> points on the bed frame, seen at `height_mm` above the bed surface (the top of
// what is seen). Throws CalibrationError for a pixel whose ray misses that plane.
std::vector<Point3> pixels_to_bed(const CameraModel& camera, const BedPlane& plane,
                                  const std::vector<Point2>& pixels, double height_mm);

}  // namespace calbox::geometry
