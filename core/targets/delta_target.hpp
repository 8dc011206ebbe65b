#pragma once
// The delta calibration artifact: ArUco markers spread over the printable area, their white
// cells (and a one-cell quiet zone) filled as zigzag raster lines at the line width so that the
// black cells are the bed showing through, plus the classic three bars along the tower
// directions. Deterministic: the same machine file gives the same job.
#include <array>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_file.hpp"

namespace calbox::targets {

struct DeltaTargetOptions {
    std::string dictionary = "DICT_4X4_50";
    double marker_mm = 12.0;  // the marker's black border edge to edge
    // Between marker centres, on a hexagonal grid (rows 0.87 of it apart): a row's rings keep
    // a millimetre and a half of bed from the next row's.
    double pitch_mm = 25.0;
    double bar_width_mm = 4.0;
    double bar_inner_radius_mm = 12.0;  // bars run from here outwards along each tower
    // A single strand across each bar's end, this much bare bed past it, as long as the bar is
    // wide: the bar's length is read between their centrelines, which stay where the nozzle
    // went whatever the strands' widths (a bar's own end faces move with its fill's).
    double bar_tick_gap_mm = 1.5;
    // Each marker's quiet zone is ringed by one strand, this much bare bed inside it: both its
    // edges show, so its centreline (where the nozzle went, whatever the strand's width) and its
    // width (the strand's height, where the nozzle pressed it) can be measured. 0.8 mm keeps an
    // edge between it and the quiet zone's fill when both are squashed to a millimetre wide.
    double outline_gap_mm = 1.5;
    int layers = 1;
};

struct TargetMarker {
    int id = 0;
    geometry::Point2 centre_mm;
    std::array<geometry::Point2, 4> corners_mm;  // OpenCV's order as seen from above (+y up)
    // The ring strand's centreline, corner for corner with `corners_mm`: the measured features.
    std::array<geometry::Point2, 4> outline_corners_mm;
    double outline_half_mm = 0;  // from the centre to each side of that centreline
};

struct TargetBar {
    char tower = 'A';
    geometry::Point2 start_mm, end_mm;  // the filled bar's centreline, outer edges included
    double width_mm = 0;
    // The end ticks' middles (the inner one first): each tick is one strand square to the bar,
    // `width_mm` long, its centreline through this point.
    std::array<geometry::Point2, 2> ticks_mm{};
    double length_mm() const;  // between the ticks' centrelines, along the tower
    // Where tick `which` (0: the inner one) starts and ends, as commanded.
    std::array<geometry::Point2, 2> tick_ends_mm(std::size_t which) const;
};

struct DeltaTarget {
    jobs::PlacedJob job;
    std::vector<TargetMarker> markers;
    std::vector<TargetBar> bars;
    double top_height_mm = 0;       // the printed surface the camera sees
    std::string fingerprint;        // of the target's geometry and the machine it was made for
    double marker_half_mm = 0;      // centre to the black border's edge
    double ring_gap_mm = 0;         // bare bed inside each marker's ring strand
    double strand_width_mm = 0;     // the line width every strand is commanded at
    double strand_section_mm2 = 0;  // its cross-section: what each millimetre extrudes
};

// Throws JobError when the machine is not a delta or the bed is too small for the layout.
DeltaTarget make_delta_target(const models::MachineFile& machine,
                              const DeltaTargetOptions& options = {});

}  // namespace calbox::targets
