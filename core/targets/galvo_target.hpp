#pragma once
// The galvo calibration artifact: an N x N grid of filled circles at pitch L over the scanner's
// field, small ones of radius 0.2 L and large ones of 0.4 L. The large ones form a layout that no
// rotation or mirror image of the square maps onto itself, so a photo of the burned grid says
// which way round it lies. Coordinates are scanner millimetres, centred on the field.
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_file.hpp"

namespace calbox::targets {

struct GalvoTargetOptions {
    int grid_count = 31;  // N: circles per row and per column
};

// A grid node by column (along scanner +x) and row (along scanner +y), from 0.
struct GridIndex {
    int column = 0, row = 0;
    bool operator==(const GridIndex&) const = default;
};

struct GalvoMark {
    GridIndex index;
    geometry::Point2 centre_mm;  // scanner millimetres
    bool large = false;
};

struct GalvoTarget {
    int grid_count = 0;
    double pitch_mm = 0;
    std::vector<GalvoMark> marks;  // row by row, index.row * grid_count + index.column
    jobs::PlacedJob job;           // every circle filled with the spot
    std::string fingerprint;       // of the layout and the machine it was made for
    const GalvoMark& at(GridIndex i) const {
        return marks[geometry::grid_offset(i.column, i.row, grid_count)];
    }
};

// Whether the grid node is one of the large circles, for a grid of `grid_count`.
bool is_large_mark(GridIndex index, int grid_count);

// The eight symmetries of the square acting on grid indices: 0 is the identity, 1-3 the
// quarter turns, 4-7 the mirror images.
GridIndex apply_symmetry(int symmetry, GridIndex index, int grid_count);

// The grid alone (its marks, pitch and fingerprint, no job): what a measurement is matched
// against, without filling 961 circles. Throws as make_galvo_target does.
GalvoTarget galvo_grid(const models::MachineFile& machine, const GalvoTargetOptions& options = {});

// Throws JobError when the machine is not a galvo, the grid is under 7 x 7 or over 101 x 101,
// or the spot is too large to fill the small circles.
GalvoTarget make_galvo_target(const models::MachineFile& machine,
                              const GalvoTargetOptions& options = {});

// A plain scanner job for controllers that take lists of marks (a vendor tool, a Modbus
// controller): one line per point, "x_mm,y_mm,power", power 0 jumps there and power > 0 marks
// the line to it, after a header line "x_mm,y_mm,power".
std::string write_scanner_job_csv(const jobs::PlacedJob& job, const models::MachineFile& machine);

}  // namespace calbox::targets
