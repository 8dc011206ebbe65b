#pragma once
// A machine job from a drawing: the SVG placed on the machine's bed (as seen from above it
// reads as drawn), filled or traced with the machine's line, and written as G-code for its kind
// (printers: extrusion; lasers and galvos: beam on/off; routers: spindle and plunge).
#include <optional>
#include <stdexcept>
#include <string>

#include "core/drawings/svg.hpp"
#include "core/jobs/toolpath.hpp"
#include "core/models/machine_file.hpp"

namespace calbox::jobs {

class JobError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct SvgJobSettings {
    std::optional<double> spacing_mm;             // default: the line width
    std::optional<double> angle_deg;              // default: whichever travels least
    std::optional<double> feed_mm_s;              // default: the machine file's
    std::optional<double> scale;                  // multiplies the drawing's millimetres
    std::optional<double> fit_mm;                 // or: the larger side becomes this long
    std::optional<drawings::FillRule> fill_rule;  // overrides every shape's own
    int perimeters = 1;
};

struct PlacedJob {
    Toolpath toolpath;
    double scale = 1;  // drawing mm -> machine mm
    double line_width_mm = 0;
    double spacing_mm = 0;
    double feed_mm_s = 0;
    int layers = 1;  // printers: the toolpath repeated one layer height higher each time
    double min_x = 0, min_y = 0, max_x = 0, max_y = 0;  // the drawing's extent on the bed
    // The same extent's corner in the document (mm, y down): the document's point
    // (x, y) lies on the bed at (min_x + (x - drawing_min.x) * scale, max_y - (y - drawing_min.y)
    // * scale).
    geometry::Point2 drawing_min;
    // Shapes that reached past the drawing's page and were cut at its edge, as a browser shows
    // them.
    int shapes_cut_at_page = 0;
    double estimated_time_s(const models::MachineFile& machine) const;
};

// The spacing a machine accepts: printers from their line width to ten times it, other
// machines 0.01 to 10 mm. Throws JobError with the valid range.
double checked_spacing_mm(const models::MachineFile& machine, std::optional<double> spacing_mm);

// Throws JobError for bad settings or a drawing that does not fit on the bed.
PlacedJob plan_svg_job(const drawings::SvgDocument& document, const models::MachineFile& machine,
                       const SvgJobSettings& settings);

// The whole job, ready to send: start, the toolpath at the working height, end.
std::string write_gcode(const PlacedJob& job, const models::MachineFile& machine,
                        const std::string& title);

}  // namespace calbox::jobs
