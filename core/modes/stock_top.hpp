#pragma once
// The stock's top above the bed, measured by the machine's own touch probe: grbl's G38.2 straight
// down on the sheet and on the bed beside it, the difference of the two heights it reports. A
// bed photo then puts the sheet's top where it is, not where the machine file says sheets are.
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/stock.hpp"

namespace calbox::modes {

// Where the probe touches, in machine coordinates: on the sheet, and on the bed beside it.
struct StockProbePoints {
    geometry::Point2 on_sheet_mm, beside_mm;
    std::string from;  // how they were chosen, for the owner: "as given", "stock.json's ..."
};

// Points `inset_mm` in from the sheet's corner nearest the machine's zero and as far out from it,
// on the line through the corner and the sheet's middle (clear of both edges by the inset's
// share of the diagonal).
StockProbePoints probe_points_at_corner(const StockOutline& stock, const std::string& source,
                                        double inset_mm = 10);

// The lines grbl is sent, in millimetres: the tool lifted to the clear height (machine Z), over
// the sheet's point, probing down (G38.2, relative, the settings' travel and feed), lifted; then
// the same beside the sheet. Every move in XY is made at the clear height.
std::vector<std::string> touch_probe_commands(const models::TouchProbeSettings& probe,
                                              const StockProbePoints& points);

// grbl's probing reports among its replies ("[PRB:-250.000,-240.000,-61.002:1]"), in order, in
// machine coordinates. Throws StockError for a report of a cycle that did not touch (":0").
std::vector<geometry::Point3> grbl_probe_touches(const std::vector<std::string>& replies);

struct StockTop {
    double surface_height_mm = 0;             // the sheet's top above the bed
    double sigma_mm = 0;                      // the two touches' repeatability together
    geometry::Point3 on_sheet_mm, beside_mm;  // the touches, machine coordinates
};
// Throws StockError naming both heights unless the sheet's touch is above the bed's, by no more
// than 200 mm, and each touch lies where it was sent in X and Y (within 0.01 mm).
StockTop stock_top_from_touches(const std::vector<geometry::Point3>& touches,
                                const StockProbePoints& points, double repeatability_mm);

// "X-250.000 Y-240.000": a machine point as the probe's lines and messages write it.
std::string machine_xy_text(geometry::Point2 p);

// The probed top's file, `calbox.stock-top/1`. Reading throws RecordError naming `source`.
std::string stock_top_to_json(const StockTop& top);
StockTop stock_top_from_json(const std::string& text, const std::string& source);

}  // namespace calbox::modes
