#pragma once
// The planar calibration artifact: a grid of holes (routers: drilled with the machine's tool)
// or dots (printers and lasers: filled discs) over the work area, in machine coordinates. Two
// holes are drilled larger and one is left out, at places no rotation or mirror image of the
// grid maps onto themselves, so a photo says which hole is which whichever way it shows the
// sheet.
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_file.hpp"
#include "core/targets/galvo_target.hpp"

namespace calbox::targets {

struct PlanarHole {
    GridIndex index;             // column along machine +x, row along +y, from 0
    geometry::Point2 centre_mm;  // machine coordinates, as commanded
    bool large = false;
    // Approached from +X +Y, against every other hole: where it lands against the model says how
    // much slack the drives have (backlash). It lies in the middle of the cell whose first node
    // is `index`.
    bool approached_backwards = false;
};

struct PlanarTargetOptions {
    // Only these grid nodes (by index into the full grid, row by row) are made, for a short
    // job chosen by DETMAX; the fiducials are always made.
    std::optional<std::vector<std::size_t>> only_nodes;
};

struct PlanarTarget {
    int columns = 0, rows = 0;
    double pitch_mm = 0;
    geometry::Point2 first_mm;  // node (0, 0)
    double hole_diameter_mm = 0, large_diameter_mm = 0;
    GridIndex omitted;  // the node left out on purpose
    // Routers: one more hole, in the middle of the grid's middle cell, approached backwards.
    std::optional<PlanarHole> backlash_hole;
    std::vector<PlanarHole> holes;  // the holes made, in the order the job makes them
    std::string job;                // G-code, ready to send
    std::string fingerprint;        // of the layout and the machine it was made for
    geometry::Point2 node_mm(GridIndex i) const {
        return {first_mm.x + i.column * pitch_mm, first_mm.y + i.row * pitch_mm};
    }
};

// Whether a node of a columns x rows grid is one of the two large holes, or the omitted one.
bool is_large_hole(GridIndex index, int columns, int rows);
GridIndex omitted_hole(int columns, int rows);

// The symmetries of a rectangle's grid acting on indices of a grid seen as `columns` x `rows`
// (quarter turns swap them): 0 identity, 1-3 quarter turns, 4-7 mirror images then turns.
// `seen_columns`/`seen_rows` become the dimensions after the map.
GridIndex apply_grid_symmetry(int symmetry, GridIndex index, int columns, int rows);
// The dimensions a columns x rows grid has after the symmetry.
std::pair<int, int> grid_dimensions_after(int symmetry, int columns, int rows);

// A router's drilling job for any holes, in its firmware's dialect (grbl and LinuxCNC dwell in
// seconds and end with M2, Marlin dwells in milliseconds): spindle on, each hole approached from
// -X -Y (so the drives' slack is taken up alike at every hole; from +X +Y when the hole says
// so), plunged to cut_depth_mm, large
// ones widened by a circle, a dwell, retract to safe_height_mm; spindle off. Z0 is the sheet's
// top.
std::string write_drilling_job(const models::MachineFile& machine,
                               const std::vector<PlanarHole>& holes, double hole_diameter_mm,
                               double large_diameter_mm, const std::string& title);

// Throws JobError when the machine is not a router, cartesian printer or laser, the work area
// holds fewer than 5 x 5 holes, or the tool is too large for the pitch.
PlanarTarget make_planar_target(const models::MachineFile& machine,
                                const PlanarTargetOptions& options = {});

}  // namespace calbox::targets
