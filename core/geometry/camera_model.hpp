#pragma once
// Camera intrinsics (OpenCV's pinhole k1 k2 p1 p2 k3 and fisheye k1..k4 models) and the
// camera.yaml format (OpenCV FileStorage YAML).
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"

namespace calbox::geometry {

enum class LensModel { pinhole, fisheye };
// "pinhole" or "fisheye", as camera.yaml and the command line write it.
const char* lens_model_name(LensModel model);

struct CameraModel {
    LensModel model = LensModel::pinhole;
    int image_width = 0;
    int image_height = 0;
    std::array<double, 9> camera_matrix{1, 0, 0, 0, 1, 0, 0, 0, 1};  // row-major K
    std::vector<double> distortion;  // pinhole: 5 coefficients; fisheye: 4
    double rms_px = 0;               // calibration reprojection RMS

    double fx() const { return camera_matrix[0]; }
    double fy() const { return camera_matrix[4]; }
    double cx() const { return camera_matrix[2]; }
    double cy() const { return camera_matrix[5]; }
};

class FileFormatError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Raw pixels -> undistorted normalized image coordinates (x/z, y/z).
std::vector<Point2> undistort_to_normalized(const CameraModel& camera,
                                            const std::vector<Point2>& pixels);
// Normalized image coordinates -> raw (distorted) pixels.
std::vector<Point2> distort_from_normalized(const CameraModel& camera,
                                            const std::vector<Point2>& normalized);
// Points in a frame with `pose` (frame -> camera) -> raw pixels.
std::vector<Point2> project_points(const CameraModel& camera, const RigidPose& pose,
                                   const std::vector<Point3>& points);

// "" when a photo of `width_px` x `height_px` is the size the camera was calibrated at, else
// "W x H, the camera was calibrated at W x H": every place a photo meets the camera says it so.
std::string photo_size_mismatch(const CameraModel& camera, int width_px, int height_px);

std::string camera_to_yaml(const CameraModel& camera,
                           const std::vector<double>& per_view_rms_px = {});
// Throws FileFormatError naming the missing or malformed key.
CameraModel camera_from_yaml(const std::string& text);

// For a catch (...) around a read of OpenCV YAML text: FileFormatError goes on as it is;
// OpenCV's errors, and the standard exceptions its parser lets out on some malformed texts (a
// std::length_error on a cut-off flow mapping, found by tests/fuzz), become
// FileFormatError("corrupt YAML: ...").
[[noreturn]] void rethrow_as_file_format_error();

// Throws FileFormatError, naming the line, for YAML that is not in the shapes the box's own
// files have (OpenCV's FileStorage writes them so): the header "%YAML:1.0" and "---", then
// `key: value` lines at the margin; a key with no value or an !!opencv-matrix tag opens a block
// of indented `key: value` or `- value` lines; a flow list ([ ] or { }) may run on over
// indented lines until it closes. Values are words and numbers, quoted text on one line, or
// lists of them. OpenCV 4.6's parser loops for ever on some texts outside these shapes (found
// by tests/fuzz), and a file the box cannot read must stop it with a message, not hang it.
void check_yaml_text(const std::string& text);

}  // namespace calbox::geometry
