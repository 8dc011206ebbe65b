#pragma once
// The stock found: a sheet lying on the bed (light or dark against it, turned any way), its four
// edges measured in the photo and its corners given in the machine's coordinates (as a job
// compensated through the planar result means them), each with its uncertainty.
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/image_view.hpp"
#include "core/modes/bed_view.hpp"
#include "core/modes/planar.hpp"

namespace calbox::modes {

class StockError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct StockCorner {
    // "front-left", "front-right", "back-right", "back-left": the machine's -Y side is the front,
    // its -X side the left.
    std::string name;
    geometry::Point2 machine_mm;
    // Standard uncertainty of each coordinate: the two edges' fits there and the camera's own
    // (the bed view's accuracy).
    double sigma_mm = 0;
};

struct StockOutline {
    std::array<StockCorner, 4> corners;  // counter-clockwise from the front-left
    double rotation_deg = 0;             // the front edge against the machine's +X
    double rotation_sigma_deg = 0;
    double width_mm = 0, depth_mm = 0;  // the front and the left edge
    bool lighter_than_bed = true;
    double surface_height_mm = 0;
    std::array<int, 4> edge_points{};  // measured on the front, right, back and left edges
    int edge_points_set_aside = 0;     // off their edge's line (a chip, a clamp, swarf)
    int edge_points_under_glare = 0;   // left out where the sensor clipped the edge
};

// Why the limits are what they are.
struct StockSettings {
    // The outline is first found on a view of the travel this many pixels across its longer
    // side (0.3 mm a pixel on a 300 mm router: an edge there is within a pixel or two, well
    // inside the search below, and the view costs a fraction of the photo's pixels).
    int rough_view_px = 1000;
    // Each edge is measured across it every this far, from this far either side of where the
    // rough outline has it (the rough view places an edge within a pixel or two of it).
    double station_step_mm = 2;
    double search_half_mm = 4;
    // Stations this near a corner are skipped: the other edge's blur and a rounded or chipped
    // corner would pull them.
    double corner_clearance_mm = 5;
    // A point this far off its edge's line is something else on it (glare, a chip, a clamp).
    double max_off_line_mm = 0.15;
    // An edge whose points left span less than this share of it (at least 8 of them) cannot be
    // told: the line's turn would rest on a short base.
    double min_span_share = 0.5;
    // A station whose photo reaches this level this near its edge was clipped by the sensor:
    // the blur's profile there is cut, and its centre moved towards the unclipped side.
    double clipped_level = 250;
    double clip_reach_px = 3;
};

// Throws StockError (one line, with what decided) when no sheet with four straight edges lies
// wholly in what the camera sees, or an edge cannot be told; BedViewError for a result that does
// not say where the bed lies or a photo of another size than the camera's.
StockOutline find_stock(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                        const vision::GrayView& photo, const PlanarSolution& solution,
                        double surface_height_mm, const std::string& source,
                        const StockSettings& settings = {});

// The bed view with its overlay (bed_view_with_overlay) and the sheet's outline drawn on it
// (orange), each corner marked and named. Three bytes a pixel, as that function gives them.
std::vector<std::uint8_t> bed_view_with_stock(const BedView& view, const PlanarSolution& solution,
                                              const StockOutline& stock);

// The stock's file, `calbox.stock/1`: the outline with the machine it was found on (the planar
// result's machine fingerprint). Reading throws RecordError naming `source`.
std::string stock_to_json(const StockOutline& stock, const std::string& machine_fingerprint);
struct StockRecord {
    StockOutline stock;
    std::string machine_fingerprint;
};
StockRecord stock_from_json(const std::string& text, const std::string& source);

// A corner by its name, or "nearest": the one nearest the machine's zero. Throws StockError
// naming the choices for another name.
const StockCorner& stock_corner(const StockOutline& stock, const std::string& name);

}  // namespace calbox::modes
