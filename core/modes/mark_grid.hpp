#pragma once
// A grid of round marks (burned spots, drilled holes, printed dots) found in a photo: each spot
// on the bed with its size and uncertainty, odd-sized ones set aside, and the rest indexed on a
// square lattice grown from the middle mark. The galvo and planar modes share it.
#include <map>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/geometry/types.hpp"
#include "core/vision/spots.hpp"

namespace calbox::modes {

class LatticeError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// A spot mapped onto the bed at the marked surface's height.
struct SeenMark {
    geometry::Point2 bed_mm;
    double radius_mm = 0;  // of the disc with the spot's area
    double sigma_mm = 0;   // standard uncertainty of each coordinate
    double elongation = 1;
    bool touches_border = false;
};
std::vector<SeenMark> marks_on_bed(const geometry::CameraModel& camera,
                                   const geometry::BedPlane& plane, const vision::SpotImage& seen,
                                   double height_mm);

// A mark of the right size for the grid, small or large, not yet placed on the lattice.
struct MarkCandidate {
    geometry::Point2 bed_mm;
    double radius_mm = 0, sigma_mm = 0;
    bool large = false;
    bool taken = false;
};

// How far the pixels of the plane's middle are apart on the bed, as pixels per mm (the geometric
// mean of the two directions): what a mark of known size spans in the photo, roughly.
double pixels_per_mm_at_centre(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               double height_mm);

// Where the work can be in the photo: a circle of `reach_mm` about the plane's origin at
// `height_mm`, through the camera, as a polygon in pixels. The board the plane was taken from lay
// on the bed, so the bed lies within its own diagonal of that origin. Empty (no limit) where the
// circle reaches behind the camera or beyond the plane's horizon.
// The margin past the work's reach: the board may lie a little off the bed's edge.
constexpr double kOutlineMarginMm = 20;
std::vector<geometry::Point2> work_outline_px(const geometry::CameraModel& camera,
                                              const geometry::BedPlane& plane, double height_mm,
                                              double reach_mm);

// Marks of one kind are made alike: one whose radius differs from its kind's median by more
// than `max_deviation` (a fraction), or by more than kSizeSpreadsAllowed times the kind's own
// spread where that is larger (holes 11 px across measure 3.5 % apart, one sigma), has something
// fused to it (spatter, a chip, a burr) or missing from it, and its centroid moved with it.
// Those are moved to `extra_mm`.
constexpr double kSizeSpreadsAllowed = 4;
void set_aside_odd_sizes(std::vector<MarkCandidate>& candidates, double max_deviation,
                         std::vector<geometry::Point2>& extra_mm);

struct LatticeNode {
    geometry::Point2 position_mm;
    long candidate = -1;  // -1: predicted through a gap, no mark there
};
using Lattice = std::map<std::pair<int, int>, LatticeNode>;

// Indexes the candidates on a square lattice of pitch `pitch` (marking the ones it takes),
// grown from the middle mark, the first axis along the bed's +x as near as a quarter turn
// allows. Throws LatticeError when no two marks lie a pitch apart.
Lattice grow_lattice(std::vector<MarkCandidate>& candidates, double pitch, double reach);

// The index box of the lattice's nodes that hold a mark.
struct LatticeExtent {
    int min_a = 0, max_a = 0, min_b = 0, max_b = 0;
    int columns() const { return max_a - min_a + 1; }
    int rows() const { return max_b - min_b + 1; }
};
LatticeExtent lattice_extent(const Lattice& lattice);

}  // namespace calbox::modes
