#pragma once
// Intrinsic calibration from board images, and the bed plane from one board lying on the bed.
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/camera_model.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "core/image_view.hpp"

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
    // What found it: "sb", "sb-normalized" or "sb-equalized" for a chessboard (below),
    // "charuco", "circles" or "circles-negative".
    std::string detector;
    // A chessboard's corners found washed out by a glare (ChessboardSearch): not among the
    // points, by id.
    std::vector<int> set_aside_ids;
};

// How a chessboard is searched for, each limit with its reason.
struct ChessboardSearch {
    // Above this long side the board is found on an image reduced by a whole factor to fit it,
    // then its corners refined at full resolution: OpenCV's SB detector costs about 7 s on a
    // 12 MP view at full size and a tenth of that on a 1600 px one, which still shows 20 mm
    // squares at 30+ px from half a metre.
    int max_search_side_px = 1600;
    // The corner refinement's half window, as a share of a square's side in pixels, and its
    // bounds: a quarter square stays inside the square's two edges at the steepest tilt the
    // detectors accept; under 3 px the saddle is not sampled, over 15 px blur and lens bend
    // enter the window.
    double refine_window_share = 0.25;
    int refine_window_min_px = 3;
    int refine_window_max_px = 15;
    // Tile-by-tile equalisation, the last try (CLAHE): tiles of the image's side over this, and
    // each tile's histogram clipped at this many times its mean before it is spread (so that a
    // flat tile's noise is not stretched into corners).
    int equalize_tiles = 8;
    double equalize_clip_limit = 4.0;
    // ... tried only on a photo more than this share clipped white: a glare to see through.
    double glare_clipped_share = 0.02;
    // A pixel at or above this is clipped white (a sensor's curve and JPEG flatten the last
    // counts before 255).
    int clipped_from_dn = 250;
    // A corner with clipped white in its refinement window and a contrast there (the brightest
    // quarter's mean less the darkest's, as a share of the brightest's) under this share of the
    // board's best corners' is washed out by a glare and set aside: its dark squares have risen
    // towards the clipped white and its saddle is pulled towards the brighter side. Vignetting
    // and light falling off across a board scale both sides alike and leave the share as it is;
    // blur and distance lower it, but a corner clipped nowhere is never set aside.
    double washed_out_contrast_share = 0.5;
};

// Empty when the board is not in the image. A chessboard is tried with OpenCV's SB detector
// without normalisation ("sb"), with it ("sb-normalized": histogram equalisation helps a
// low-contrast board but defeats SB on dark surroundings), then exhaustively on the image
// equalised tile by tile ("sb-equalized": squares washed out by a glare); SB's own accurate
// corners at full size, else cornerSubPix at full resolution. Corners under clipped white are
// set aside (set_aside_ids). OpenCV's classic detector is not tried: it found
// no board in the tests that SB missed, and on a ChArUco board (many small squares) it takes
// two minutes to say no.
// ChArUco boards through marker detection and corner interpolation (at least 6 corners), dot
// grids through findCirclesGrid (dark dots on light, or light on dark). Throws
// CalibrationError for an ArUco grid, which has no board corners.
std::optional<BoardObservation> find_board(const PatternSpec& pattern,
                                           const vision::GrayView& image,
                                           const ChessboardSearch& search = {});
// Why find_board found no board in `image`, for the owner: the board's kind, and the lamp's glare
// where over a twentieth of the photo is clipped white.
std::string board_not_found(const PatternSpec& pattern, const vision::GrayView& image,
                            const ChessboardSearch& search);

struct NamedImage {
    std::string name;
    vision::GrayView image;
};

struct ViewReport {
    std::string name;
    int points = 0;
    double rms_px = 0;
    std::string detector;  // BoardObservation::detector
    std::string note;      // empty, or how the view was brought round ("re-solved: ...")
};

struct DroppedView {
    std::string name;
    std::string why;
};

struct CalibrationResult {
    CameraModel camera;
    std::vector<ViewReport> views;     // used views with their reprojection RMS
    std::vector<std::string> skipped;  // images where the board was not found
    std::vector<DroppedView> dropped;  // boards found but far off the others, left out
};

// What a calibration needs before it is tried: views, since each view's pose is unknown and
// only differing poses separate focal length from distance; and corners, for the model's
// parameters (a pinhole's 9, a fisheye's 8) with room to average the noise. At least 3 views
// and 60 corners for a pinhole (OpenCV's own ChArUco tutorial calibrates from a few photos);
// a fisheye's distortion reaches the image's edges and needs 4 and 80.
struct CalibrationMinimum {
    int views = 0;
    int corners = 0;
};
CalibrationMinimum calibration_minimum(LensModel model);

struct ObservedView {
    std::string name;
    BoardObservation board;
};

// How the views judge each other. A view reprojecting beyond `outlier_factor` times the better
// views' RMS (their lower quartile) (and beyond `outlier_floor_px`, under which every view of a
// real lens is fine) is set aside: on BoofCV's fisheye set two views whose pose OpenCV's start did
// not converge sit at 100 px while the other 22 are at 0.18-0.50 px, and they drag the whole solve
// to 31 px.
struct ViewJudging {
    double outlier_factor = 5;
    double outlier_floor_px = 1.0;
};

// The RMS over the kept views past which a calibration is refused: a real pinhole lens
// calibrates to a few tenths of a pixel, a fisheye's wider field a little more; beyond these the
// lens model is wrong or the board bowed, and every measurement through it would be.
double calibration_max_rms_px(LensModel model);

// The solve alone, from boards already found (the box finds each view's board as it is taken,
// to say at once whether it counts). Views far off the others are re-solved through the rest's
// camera or dropped (CalibrationResult::views' notes and ::dropped say which and why). Throws
// CalibrationError, nothing solved, when the views left fall short of calibration_minimum or
// the RMS exceeds calibration_max_rms_px; the same errors as calibrate_camera otherwise.
CalibrationResult calibrate_from_views(LensModel model, const std::vector<ObservedView>& views,
                                       int width_px, int height_px,
                                       const ViewJudging& judging = {});

// One board's pose through a known camera (board frame -> camera). Throws CalibrationError when
// it cannot be solved or lies behind the camera.
RigidPose solve_board_pose(const CameraModel& camera, const BoardObservation& board);

// How much of the image the views' corners cover: the share of an 8 x 6 grid of cells holding
// at least one corner. A calibration whose corners all sit in the middle extrapolates the
// lens's distortion to the edges, where the bed's far corners are.
double image_coverage(const std::vector<ObservedView>& views, int width_px, int height_px);

// Throws CalibrationError when the usable views fall short of calibration_minimum (naming what
// was found and what is needed), when images differ in size, or when OpenCV's solver fails.
CalibrationResult calibrate_camera(const PatternSpec& pattern, LensModel model,
                                   const std::vector<NamedImage>& images);

// The bed frame: right-handed, z up out of the bed, origin under the board's first inner corner,
// x along the board's columns; OpenCV's board frame (z into the board) turned over about x.
struct BedPlane {
    RigidPose bed_to_camera;
    double board_thickness_mm = 0;
    double rms_px = 0;
    std::vector<int> set_aside_corners;  // found under glare, left out of the fit (not stored)
    int corners_used = 0;                // not stored
};

// The board's corners reproject through the plane's pose within this: a flat board seen through
// its own camera's model fits to a few tenths of a pixel; past a pixel the board is bowed or
// lifted, the corners were found wrong, or the camera model is another camera's.
constexpr double kPlaneMaxRmsPx = 1.0;

// Throws CalibrationError when the board is not found, its pose cannot be solved, or its
// reprojection RMS exceeds `max_rms_px` (the message gives the figure), or when glare leaves
// fewer than half the board's corners (the share and what to do are in the message).
BedPlane estimate_bed_plane(const CameraModel& camera, const PatternSpec& pattern,
                            const vision::GrayView& image, double board_thickness_mm,
                            double max_rms_px = kPlaneMaxRmsPx);

// "" or ", N of its M corners set aside under glare (ids a, b, ...)": what a report of the plane
// adds, so that an owner sees the lamp's reflection on the board.
std::string set_aside_text(const BedPlane& plane);

std::string plane_to_yaml(const BedPlane& plane);
BedPlane plane_from_yaml(const std::string& text);  // throws FileFormatError

// Raw pixels -> points on the bed frame, seen at `height_mm` above the bed surface (the top of
// what is seen). Throws CalibrationError for a pixel whose ray misses that plane.
std::vector<Point3> pixels_to_bed(const CameraModel& camera, const BedPlane& plane,
                                  const std::vector<Point2>& pixels, double height_mm);

}  // namespace calbox::geometry
