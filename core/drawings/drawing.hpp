#pragma once
// A drawing as people make it, read as a browser paints it: librsvg (the renderer GNOME and
// Wikipedia use) resolves its CSS, <use> and <symbol>, nested viewports, markers and <text> (as
// the outlines of the font it names, from the fonts the system has) and paints it through
// cairo's SVG surface into plain geometry, which parse_svg reads. calbox's own work starts from
// what librsvg hands over: strokes traced, fills filled, clip paths cutting them.
//
// Its own library (calbox_drawing): librsvg, cairo and fontconfig are linked by what reads
// drawings, not by everything that uses the core.
#include <string_view>

#include "core/drawings/svg.hpp"

namespace calbox::drawings {

// Throws SvgError with one line naming the problem: parse_svg's (malformed XML with its line,
// too large, a geometry value or path data that does not read), no SVG namespace, nothing
// drawable. Warnings: styling values ignored, images and masks not drawn, a font the document
// names that the system does not have (with the one librsvg drew the text in).
SvgDocument read_drawing(std::string_view text, const SvgOptions& options = {});

}  // namespace calbox::drawings
