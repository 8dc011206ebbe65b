#pragma once
// The delta calibration artifact: ArUco markers spread over the printable area, their white
// cells (and a one-cell quiet zone) filled as zigzag raster lines at the line width so that the
// black cells are the bed showing through, plus the classic three bars along the tower
// directions. Deterministic: the same machine file gives the same job.
#include <array>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/models/machine_file.hpp"
#include "core/targets/job.hpp"

namespace calbox::targets {

struct DeltaTargetOptions {
    std::string dictionary = "DICT_4X4_50";
    double marker_mm = 12.0;  // the marker's black border edge to edge
    double pitch_mm = 21.0;   // between marker centres, on a hexagonal grid
    double bar_width_mm = 4.0;
    double bar_inner_radius_mm = 12.0;  // bars run from here outwards along each tower
    int layers = 1;
};

struct TargetMarker {
    int id = 0;
    geometry::Point2 centre_mm;
    std::array<geometry::Point2, 4> corners_mm;  // OpenCV's order as seen from above (+y up)
};

struct TargetBar {
    char tower = 'A';
    geometry::Point2 start_mm, end_mm;  // the bar's centreline, outer edges included
    double width_mm = 0;
    double length_mm() const;  // edge to edge along the tower, as a vernier reads it
};

struct DeltaTarget {
    PlacedJob job;
    std::vector<TargetMarker> markers;
    std::vector<TargetBar> bars;
    double top_height_mm = 0;  // the printed surface the camera sees
    std::string fingerprint;   // of the target's geometry and the machine it was made for
};

// Throws JobError when the machine is not a delta or the bed is too small for the layout.
DeltaTarget make_delta_target(const models::MachineFile& machine,
                              const DeltaTargetOptions& options = {});

}  // namespace calbox::targets
