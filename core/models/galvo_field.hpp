#pragma once
// The galvo field map: where a scanner's marks land for the points it was told to mark, from a
// measured grid, and the correction table that inverts it. The grid is regular in the space it
// was commanded in, so the map is a C1 bicubic (Catmull-Rom) interpolant over the grid's own
// nodes, exact at every measured node, and the table is that map inverted exactly (a fixed-point
// iteration) at the nodes of a regular grid over the largest rectangle inside the measured field.
// Controllers read such tables with bilinear interpolation, and so does `command_for`.
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"

namespace calbox::models {

class FieldError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Values on a square grid of count x count nodes at `pitch_mm`, centred on the origin, row by
// row (row along +y, column along +x).
struct SquareGrid {
    int count = 0;
    double pitch_mm = 0;
    geometry::Point2 node_mm(int column, int row) const;
    double half_span_mm() const { return 0.5 * (count - 1) * pitch_mm; }
};

// A C1 map over a square grid's nodes (Catmull-Rom in each direction; linear continuation one
// node beyond the edge).
class GridMap {
  public:
    GridMap(SquareGrid grid, std::vector<geometry::Point2> values);
    geometry::Point2 operator()(geometry::Point2 at_mm) const;
    const SquareGrid& grid() const { return grid_; }

  private:
    geometry::Point2 node(int column, int row) const;
    SquareGrid grid_;
    std::vector<geometry::Point2> values_;
};

// A correction table: for each node of a regular grid over a rectangle of intended positions
// (field millimetres), the scanner command that marks there.
struct CorrectionTable {
    int nodes = 65;  // per side: the size EZCAD- and SCANLAB-style tables use
    double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
    std::vector<geometry::Point2> command_mm;  // row by row from (min_x, min_y)

    geometry::Point2 node_mm(int column, int row) const;
    bool covers(geometry::Point2 intended_mm) const;
    // Bilinear in the table's corrections (command minus intended); outside the rectangle the
    // edge's correction continues unchanged.
    geometry::Point2 command_for(geometry::Point2 intended_mm) const;
};

// The identity: a scanner that has never been corrected.
CorrectionTable identity_table(double half_span_mm, int nodes = 65);

struct ErrorStatistics {
    double mean_mm = 0, rms_mm = 0, max_mm = 0;
    std::size_t points = 0;
};
ErrorStatistics error_statistics(const std::vector<geometry::Point2>& errors_mm);

struct FieldFit {
    // Where each node's mark landed in the field frame (the measured frame turned and shifted
    // onto the intended grid), row by row; nodes without a measurement filled from their
    // neighbours and flagged.
    std::vector<geometry::Point2> landed_mm;
    std::vector<bool> filled;
    ErrorStatistics before;  // |landed - intended| over the measured nodes
    CorrectionTable table;
    // Largest and RMS difference, at the table cells' middles, between the exact inverse and the
    // table's bilinear reading: what the table's resolution costs.
    double table_interpolation_max_mm = 0, table_interpolation_rms_mm = 0;
    // How far each measured mark lies from the smooth field through its neighbours (RMS, in the
    // plane): the burn's repeatability and the measurement's noise together, which the table,
    // fitted through every node, carries into each later burn. Zero when too few rows of five
    // measured nodes exist to tell.
    double node_scatter_mm = 0;
};

// `intended` is the grid the marks were meant to land on; each mark was commanded through
// `burned_through` (the identity on a first pass, the table in force on a later one). `landed`
// holds each node's measured position (any frame: it is turned and shifted onto the grid), empty
// where the mark was not measured. Throws FieldError when under three quarters of the nodes, or
// a whole border row or column, were measured, or when the map folds (cannot be inverted).
FieldFit fit_galvo_field(const SquareGrid& intended,
                         const std::vector<std::optional<geometry::Point2>>& landed,
                         const CorrectionTable& burned_through, int table_nodes = 65);

// The table as CSV: a comment line with the rectangle, a header, then one line per node
// "column,row,x_mm,y_mm,command_x_mm,command_y_mm" (micrometre resolution).
std::string table_to_csv(const CorrectionTable& table);
// Throws FieldError naming the line at fault.
CorrectionTable table_from_csv(const std::string& text, const std::string& source);

}  // namespace calbox::models
