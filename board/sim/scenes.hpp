#pragma once
#include <array>
// What lies on a plane in front of the camera, evaluated over one pixel's footprint so that
// the rendered edges sit where the geometry puts them (exact half-plane area coverage).
#include <memory>
#include <string>
#include <vector>

#include "board/sim/camera_reference.hpp"
#include "core/geometry/pattern_spec.hpp"

namespace calbox::sim {

// One camera pixel seen on a plane: where its centre's ray meets the plane (z = 0 of the
// plane's frame), how plane coordinates change across the pixel, and how the meeting point
// moves per mm of height above the plane.
struct Footprint {
    Vec2 centre_mm;
    double jacobian[2][2];  // d(plane x, y) / d(pixel u, v)
    Vec2 shift_per_height;  // d(plane x, y) / d(height)
};

class Scene {
  public:
    virtual ~Scene() = default;
    // Mean reflectance over the pixel, 0 (black) to 1 (white).
    virtual double albedo(const Footprint& f) const = 0;
};

// Fraction of a pixel (or of a 1/subdivisions sub-square) on the inner side of a straight edge:
// signed distance of its centre (negative inside), the edge's outward unit normal in plane mm.
double inside_fraction(double signed_distance_mm, Vec2 outward_normal, const double jacobian[2][2],
                       int subdivisions);

// Extruded or burned material: round-ended strokes of given width whose top lies at the
// height of their end points.
struct StrokeSegment {
    Vec3 a_mm, b_mm;
    double width_mm;
};

// What a real bed and filament add to the plain two-tone picture: a textured sheet's grain
// (multiplicative on the bed's albedo) and a glossy filament's highlight, where a strand's
// round top turns a single light towards the camera (above the bed, looking down).
struct StrokeSurface {
    double bed_texture = 0;  // relative albedo swing of the grain, 0 for a smooth sheet
    double bed_texture_grain_mm = 0.4;
    double gloss = 0;              // the highlight's peak, in albedo units added to the material's
    double light_azimuth_deg = 0;  // where the light stands, seen from the bed's centre
    double light_elevation_deg = 30;  // its height above the bed's plane
};

// The largest a camera pixel's footprint gets on a plane `distance_mm` away, for StrokeScene's
// index: three of the camera's pixels there (a pixel's own reach is about two; the third covers
// the frame's edges and a tilt). The photo is the same with any larger figure, only slower.
double stroke_footprint_mm(const CameraIntrinsics& camera, double distance_mm);

class StrokeScene final : public Scene {
  public:
    // `footprint_mm`: the largest a pixel's footprint on the plane gets (the index lists each
    // stroke in the cells it can reach from that far); fine marks seen through a fine camera
    // render much faster with a footprint to match.
    StrokeScene(std::vector<StrokeSegment> strokes, double bed_albedo, double material_albedo,
                int supersample, double footprint_mm = 1.0, const StrokeSurface& surface = {});
    ~StrokeScene() override;
    double albedo(const Footprint& f) const override;

  private:
    struct Index;
    std::vector<StrokeSegment> strokes_;
    std::unique_ptr<Index> index_;
    double bed_albedo_, material_albedo_;
    int supersample_;
    StrokeSurface surface_;
    Vec2 gloss_half_vector_xy_;  // the in-plane part of the unit vector between light and camera
    double gloss_half_vector_z_ = 1;
    double bed_at(Vec2 p) const;
};

// A calibration board on its own plane, with a white margin, on a grey background.
// Chessboard frame: origin at the first inner corner, x along columns, y along rows (OpenCV's
// object points). ChArUco and ArUco grid frames: OpenCV's board frames. Dot grids: OpenCV's
// findCirclesGrid object points, dots a quarter pitch in radius.
// What lies around the board's paper: a mid grey; a dark cloth or bed; a white wall or sheet
// (the paper's edge barely shows); a cluttered bench of board-sized patches of random greys
// (false corners everywhere around the board).
enum class Surroundings { grey, dark, bright, cluttered };

class BoardScene final : public Scene {
  public:
    BoardScene(const geometry::PatternSpec& spec, int supersample,
               Surroundings surroundings = Surroundings::grey);
    ~BoardScene() override;
    double albedo(const Footprint& f) const override;

    struct Feature {
        int id;  // chessboard: corner index; charuco: corner id, or marker id for marker corners
        int corner = -1;  // marker corner 0..3 (OpenCV's order), -1 for a board corner
        Vec3 position_mm;
    };
    // Inner (chessboard / ChArUco) corners, then ChArUco marker corners.
    std::vector<Feature> features() const;

    struct Layout;

  private:
    std::unique_ptr<Layout> layout_;
    int supersample_;
};

// A rectangular sheet of stock lying on the bed, anywhere and turned: its corner at `corner_mm`,
// `width_mm` along its own x (turned `angle_deg` from the bed's x), `depth_mm` along its own y.
// The scene's plane is the sheet's top; the bed around it is a flat albedo. Edges are covered
// exactly (each sub-square's share on the sheet's side of its nearest edge).
struct StockSheet {
    Vec2 corner_mm;
    double width_mm = 0, depth_mm = 0, angle_deg = 0;
    double sheet_albedo = 0.8, bed_albedo = 0.2;
};

class SheetScene final : public Scene {
  public:
    SheetScene(const StockSheet& sheet, int supersample);
    double albedo(const Footprint& f) const override;
    // The sheet's corners on the bed, counter-clockwise from `corner_mm`.
    std::array<Vec2, 4> corners() const;

  private:
    StockSheet sheet_;
    int supersample_;
    Vec2 along_, across_;  // the sheet's own unit x and y on the bed
};

// Fixed reference marks stuck on the bed over whatever `inner` shows: each a white square sticker
// holding one ArUco marker with a two-cell white margin (a narrower quiet zone lost AprilTag
// 36h11 markers to OpenCV's detector on the dark bed). `inner`'s plane frame maps to the bed's
// by bed = A p + b (identity for the bed itself; a board lying face up turns y over).
struct ReferenceMark {
    int id;
    Vec2 centre_mm;  // on the bed
};

// Half the side of the white sticker that carries a `marker_mm` marker of `dictionary`.
double reference_sticker_half_side_mm(const std::string& dictionary, double marker_mm);

class ReferenceMarksScene final : public Scene {
  public:
    ReferenceMarksScene(const Scene& inner, const std::vector<ReferenceMark>& marks,
                        const std::string& dictionary, double marker_mm, int supersample,
                        const double inner_to_bed[2][2], Vec2 inner_origin_on_bed);
    ~ReferenceMarksScene() override;
    double albedo(const Footprint& f) const override;

  private:
    struct Sticker;
    const Scene& inner_;
    std::vector<Sticker> stickers_;
    double marker_mm_;
    int supersample_;
    double a_[2][2];
    Vec2 b_;
};

// The distance from `p` to the nearest point of the polyline through `line` (the judges' measure
// of a cut against the line printed for it).
double distance_to_polyline(Vec2 p, const std::vector<Vec2>& line);

}  // namespace calbox::sim
