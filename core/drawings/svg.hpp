#pragma once
// An SVG reader for plain geometry: polygon, polyline, rect (with rounded corners), circle,
// ellipse, line and path (M L H V C S Q T A Z, absolute and relative), transforms on elements
// and groups, <use> of an element or a <symbol>, clip paths, viewBox / width / height with units.
// Curves are flattened to a stated tolerance. Coordinates come out in millimetres, in SVG's
// orientation (y down). Styling is read from presentation attributes and style="" only: a
// drawing as people make it (CSS, text, markers) is read through core/drawings/drawing, which has
// librsvg paint it into this plain form first.
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/geometry/types.hpp"

namespace calbox::drawings {

// A CSS pixel (1/96 in), the unit of a length without one, in millimetres.
constexpr double kMmPerCssPixel = 25.4 / 96.0;

class SvgError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

enum class FillRule { nonzero, evenodd };

struct Contour {
    std::vector<geometry::Point2> points;
    bool closed = false;
};

struct SvgShape {
    std::string element;  // "path", "rect", ...
    std::vector<Contour> contours;
    bool filled = true;
    FillRule fill_rule = FillRule::nonzero;
    bool stroked = false;
    double stroke_width_mm = 0;
    // Where a clip path lets the shape show (a resolved region in millimetres); none: anywhere.
    std::optional<std::vector<std::vector<geometry::Point2>>> clip_region;
};

struct SvgDocument {
    std::vector<SvgShape> shapes;
    double width_mm = 0, height_mm = 0;  // the viewport
    // What was ignored as a browser ignores it (a styling value that does not parse, an image),
    // one line each.
    std::vector<std::string> warnings;
};

struct SvgOptions {
    double tolerance_mm = 0.005;  // largest distance of a flattened curve from the true one
    std::size_t max_bytes = 10u * 1024u * 1024u;  // larger documents are refused
};

// A 2-D affine map as SVG writes it: x' = a x + c y + e, y' = b x + d y + f.
struct Affine {
    double a = 1, b = 0, c = 0, d = 1, e = 0, f = 0;
    geometry::Point2 apply(geometry::Point2 p) const {
        return {a * p.x + c * p.y + e, b * p.x + d * p.y + f};
    }
    Affine then(const Affine& outer) const;  // this first, then outer
    double scale() const;                    // sqrt(|det|)
};

// Throws SvgError with one line naming the problem: malformed XML (with its line), no <svg>
// root, nothing drawable, too large, an unknown path command, a non-numeric geometry attribute,
// <text> (convert it to paths, or read the drawing through read_drawing).
SvgDocument parse_svg(std::string_view text, const SvgOptions& options = {});

// The checks parse_svg makes of every element's geometry (path data, numbers, transforms), made
// of all of a document's elements, those only used or hidden included, and nothing drawn: what a
// browser would quietly drop part of (a path cut at a bad command) is refused before a renderer
// paints the rest. Returns the document's page (width_mm, height_mm: 0 where it gives none) and
// the styling values ignored, as parse_svg's warnings; its shapes are not read.
SvgDocument check_svg_geometry(std::string_view text, const SvgOptions& options = {});

// Path data alone, mapped through `to_mm` and flattened to `tolerance_mm`.
std::vector<Contour> parse_path_data(std::string_view d, const Affine& to_mm, double tolerance_mm);
Affine parse_transform(std::string_view text);

}  // namespace calbox::drawings
