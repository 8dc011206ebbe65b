#include "core/drawings/svg.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <numbers>
#include <optional>
#include <pugixml.hpp>

#include "core/drawings/region.hpp"
#include "core/drawings/svg_path.hpp"
#include "core/number_text.hpp"

namespace calbox::drawings {
namespace {

using svg_path::arc_to;
using svg_path::flatten_arc;
using svg_path::Scanner;

using geometry::Point2;

// ---------------------------------------------------------------------------------------------
// Attributes

std::optional<double> length_in_px(std::string_view text) {
    Scanner s(text);
    const auto v = s.number();
    if (!v) return std::nullopt;
    std::string unit(text.substr(s.position()));
    while (!unit.empty() && std::isspace(static_cast<unsigned char>(unit.back()))) unit.pop_back();
    static const std::map<std::string, double> kPx{{"", 1.0},
                                                   {"px", 1.0},
                                                   {"mm", 1 / kMmPerCssPixel},
                                                   {"cm", 10 / kMmPerCssPixel},
                                                   {"in", 96.0},
                                                   {"pt", 96.0 / 72},
                                                   {"pc", 16.0},
                                                   {"q", 0.25 / kMmPerCssPixel}};
    const auto it = kPx.find(unit);
    if (it == kPx.end()) return std::nullopt;
    return *v * it->second;
}

std::string element_name(const pugi::xml_node& node) {
    std::string name = node.name();
    const auto colon = name.find(':');
    return colon == std::string::npos ? name : name.substr(colon + 1);
}

double number_attribute(const pugi::xml_node& node, const char* name, double fallback,
                        bool length = true) {
    const auto attribute = node.attribute(name);
    if (!attribute) return fallback;
    const std::string text = attribute.value();
    const auto plain_number = [&]() -> std::optional<double> {
        Scanner s(text);
        const auto v = s.number();
        return v && s.at_end() ? v : std::nullopt;
    };
    const std::optional<double> v = length ? length_in_px(text) : plain_number();
    if (!v) {
        throw SvgError("non-numeric attribute " + std::string(name) + "=\"" + text + "\" on <" +
                       element_name(node) + ">");
    }
    return *v;
}

std::vector<Point2> point_list(const pugi::xml_node& node) {
    Scanner s(node.attribute("points").value());
    std::vector<Point2> points;
    while (!s.at_end()) {
        const auto x = s.number();
        const auto y = x ? s.number() : std::nullopt;
        if (!x || !y) {
            throw SvgError(std::string("non-numeric attribute points=\"") +
                           node.attribute("points").value() + "\" on <" + element_name(node) + ">");
        }
        points.push_back({*x, *y});
    }
    return points;
}

// Presentation attributes and style properties, inherited from groups.
struct Style {
    bool filled = true;
    bool stroked = false;
    FillRule fill_rule = FillRule::nonzero;
    double stroke_width_px = 1;
    bool visible = true;
};

// A styling value that does not parse is ignored, as a browser ignores it (the inherited value
// stands), with a warning naming it; a geometry value that does not parse is refused.
void apply_property(Style& style, const std::string& name, std::string value,
                    const pugi::xml_node& node, std::vector<std::string>& warnings) {
    while (!value.empty() && std::isspace(static_cast<unsigned char>(value.back())))
        value.pop_back();
    while (!value.empty() && std::isspace(static_cast<unsigned char>(value.front())))
        value.erase(0, 1);
    if (name == "fill") {
        style.filled = value != "none" && value != "transparent";
    } else if (name == "stroke") {
        style.stroked = value != "none" && value != "transparent" && !value.empty();
    } else if (name == "fill-rule") {
        style.fill_rule = value == "evenodd" ? FillRule::evenodd : FillRule::nonzero;
    } else if (name == "stroke-width") {
        const auto v = length_in_px(value);
        if (!v || *v < 0) {
            warnings.push_back("ignored stroke-width \"" + value + "\" on <" + element_name(node) +
                               "> (not a length), as a browser ignores it");
            return;
        }
        style.stroke_width_px = *v;
    } else if (name == "display") {
        if (value == "none") style.visible = false;
    } else if (name == "visibility") {
        style.visible = value != "hidden" && value != "collapse";
    }
}

std::string without_spaces(std::string text) {
    text.erase(
        std::remove_if(text.begin(), text.end(), [](unsigned char c) { return std::isspace(c); }),
        text.end());
    return text;
}

// The declarations of a style="" attribute, name and value, in order.
std::vector<std::pair<std::string, std::string>> style_declarations(const pugi::xml_node& node) {
    const std::string style = node.attribute("style").value();
    std::vector<std::pair<std::string, std::string>> declarations;
    std::size_t start = 0;
    while (start < style.size()) {
        const auto end = std::min(style.find(';', start), style.size());
        const std::string item = style.substr(start, end - start);
        const auto colon = item.find(':');
        if (colon != std::string::npos)
            declarations.emplace_back(without_spaces(item.substr(0, colon)),
                                      item.substr(colon + 1));
        start = end + 1;
    }
    return declarations;
}

Style style_of(const pugi::xml_node& node, Style inherited, std::vector<std::string>& warnings) {
    for (const char* name :
         {"fill", "stroke", "fill-rule", "stroke-width", "display", "visibility"}) {
        if (const auto a = node.attribute(name))
            apply_property(inherited, name, a.value(), node, warnings);
    }
    for (const auto& [name, value] : style_declarations(node))
        apply_property(inherited, name, value, node, warnings);
    return inherited;
}

// ---------------------------------------------------------------------------------------------

using Region = std::optional<std::vector<Polygon>>;

// "url(#id)" -> "id"; empty when it is not a local reference.
std::string local_reference(const std::string& value) {
    const std::string text = without_spaces(value);
    if (text.rfind("url(#", 0) != 0 || text.back() != ')') return {};
    return text.substr(5, text.size() - 6);
}

// A property given as an attribute or in style="" (the style wins, as in CSS).
std::string property_of(const pugi::xml_node& node, const std::string& name) {
    std::string value = node.attribute(name.c_str()).value();
    for (const auto& [key, declared] : style_declarations(node))
        if (key == name) value = declared;
    return value;
}

struct Reader {
    SvgOptions options;
    SvgDocument document;
    // check_svg_geometry: every element's geometry is read, wherever it stands, and nothing kept.
    bool checking = false;
    std::map<std::string, pugi::xml_node> by_id;
    std::size_t instances = 0;

    // Groups nest this deep at most: drawing programs nest a few levels, a document nested
    // thousands deep is made to exhaust a reader's stack.
    static constexpr int kDeepestGroup = 256;
    // Elements drawn through <use>: a few thousand in a real drawing; references nested to
    // multiply without end are a document made to exhaust its reader.
    static constexpr std::size_t kMostInstances = 200000;

    void index(const pugi::xml_node& root) {
        std::vector<pugi::xml_node> pending{root};
        while (!pending.empty()) {
            const auto node = pending.back();
            pending.pop_back();
            if (const auto id = node.attribute("id")) by_id.emplace(id.value(), node);
            for (const auto& child : node.children())
                if (child.type() == pugi::node_element) pending.push_back(child);
        }
    }

    void element(const pugi::xml_node& node, const Affine& parent, const Style& parent_style,
                 int depth = 0, const Region& clip = std::nullopt) {
        if (depth > kDeepestGroup)
            throw SvgError("groups nested deeper than " + std::to_string(kDeepestGroup) +
                           " levels: not a drawing");
        const std::string name = element_name(node);
        const bool container = name == "g" || name == "a" || name == "switch";
        if (checking && (name == "text" || name == "style" || name == "title" || name == "desc" ||
                         name == "metadata"))
            return;  // no geometry of its own
        if (!checking &&
            (name == "defs" || name == "title" || name == "desc" || name == "metadata" ||
             name == "style" || name == "clipPath" || name == "mask" || name == "symbol" ||
             name == "marker" || name == "pattern")) {
            return;  // not drawn where it stands
        }
        if (name == "text")
            throw SvgError(
                "<text> is not drawn by a machine: convert text to paths (Inkscape: Path > "
                "Object to Path)");
        if (name == "image") {
            document.warnings.emplace_back("ignored <image>: a machine draws no bitmap");
            return;
        }
        const Style style = style_of(node, parent_style, document.warnings);
        if (!style.visible && !checking) return;
        Affine transform = parent;
        if (const auto t = node.attribute("transform")) {
            try {
                transform = parse_transform(t.value()).then(parent);
            } catch (const SvgError& e) {
                throw SvgError(std::string(e.what()) + " on <" + name + ">");
            }
        }
        if (checking) {
            if (name == "use") {
                number_attribute(node, "x", 0);
                number_attribute(node, "y", 0);
            }
            geometry_of(node, name, transform);
            for (const auto& child : node.children())
                if (child.type() == pugi::node_element) element(child, transform, style, depth + 1);
            return;
        }
        if (!node.attribute("mask").empty()) note_mask(node);
        const Region region = clip_of(node, transform, clip);
        if (container) {
            for (const auto& child : node.children()) {
                if (child.type() == pugi::node_element)
                    element(child, transform, style, depth + 1, region);
            }
            return;
        }
        if (name == "use") {
            use(node, transform, style, depth, region);
            return;
        }
        std::vector<Contour> contours = geometry_of(node, name, transform);
        if (contours.empty()) return;
        SvgShape shape;
        shape.element = name;
        shape.contours = std::move(contours);
        shape.filled = style.filled && name != "line";  // a filled polyline closes implicitly
        shape.fill_rule = style.fill_rule;
        shape.stroked = style.stroked;
        shape.stroke_width_mm = style.stroke_width_px * transform.scale();
        shape.clip_region = region;
        if (!shape.filled && !shape.stroked) return;  // invisible
        document.shapes.push_back(std::move(shape));
    }

    // <use>: the element (or a <symbol>'s content) it names, drawn again at x, y.
    void use(const pugi::xml_node& node, const Affine& transform, const Style& style, int depth,
             const Region& clip) {
        std::string href = node.attribute("href").value();
        if (href.empty()) href = node.attribute("xlink:href").value();
        const auto target =
            href.size() > 1 && href[0] == '#' ? by_id.find(href.substr(1)) : by_id.end();
        if (target == by_id.end()) {
            document.warnings.push_back("ignored <use href=\"" + href +
                                        "\">: no element of the document has that id");
            return;
        }
        if (++instances > kMostInstances)
            throw SvgError("more than " + std::to_string(kMostInstances) +
                           " elements drawn through <use>: not a drawing");
        const Affine at =
            Affine{1, 0, 0, 1, number_attribute(node, "x", 0), number_attribute(node, "y", 0)}.then(
                transform);
        if (element_name(target->second) != "symbol") {
            element(target->second, at, style, depth + 1, clip);
            return;
        }
        const Style inside = style_of(target->second, style, document.warnings);
        for (const auto& child : target->second.children())
            if (child.type() == pugi::node_element) element(child, at, inside, depth + 1, clip);
    }

    // The region a clip-path="url(#id)" lets show, within the one inherited: its <clipPath>'s
    // shapes, in the user space of the element it clips, each filled by its clip-rule.
    Region clip_of(const pugi::xml_node& node, const Affine& transform, const Region& inherited) {
        const std::string value = property_of(node, "clip-path");
        if (value.empty() || value == "none") return inherited;
        const std::string id = local_reference(value);
        const auto found = by_id.find(id);
        if (found == by_id.end() || element_name(found->second) != "clipPath") {
            document.warnings.push_back("ignored clip-path \"" + value + "\" on <" +
                                        element_name(node) + ">: no <clipPath> of that id");
            return inherited;
        }
        const auto& clip_path = found->second;
        if (std::string(clip_path.attribute("clipPathUnits").value()) == "objectBoundingBox")
            throw SvgError("clipPathUnits=\"objectBoundingBox\" on <clipPath id=\"" + id +
                           "\"> is not read: give the clip in user space");
        Affine space = transform;
        if (const auto t = clip_path.attribute("transform"))
            space = parse_transform(t.value()).then(transform);
        // cairo writes the rule on the clipped group; a clip path's own shapes may give theirs.
        const std::string rule_of_group = property_of(node, "clip-rule");
        std::vector<Contour> outlines;
        for (const auto& child : clip_path.children()) {
            if (child.type() != pugi::node_element) continue;
            Affine child_space = space;
            if (const auto t = child.attribute("transform"))
                child_space = parse_transform(t.value()).then(space);
            std::string rule = property_of(child, "clip-rule");
            if (rule.empty()) rule = rule_of_group;
            const auto rule_of =
                rule.find("evenodd") != std::string::npos ? FillRule::evenodd : FillRule::nonzero;
            for (auto& polygon :
                 resolve_fill(geometry_of(child, element_name(child), child_space), rule_of))
                outlines.push_back({std::move(polygon), true});
        }
        auto region = resolve_fill(outlines, FillRule::nonzero);
        if (inherited) region = intersect_region(*inherited, region);
        return region;
    }

    // A mask is not drawn through: a laser burns what a mask fades. cairo's own masks (a
    // group's opacity: one rectangle) say nothing of the shapes, another mask is named.
    void note_mask(const pugi::xml_node& node) {
        const auto found = by_id.find(local_reference(property_of(node, "mask")));
        bool opacity_only = found != by_id.end();
        if (opacity_only) {
            std::vector<pugi::xml_node> pending{found->second};
            while (!pending.empty() && opacity_only) {
                const auto n = pending.back();
                pending.pop_back();
                for (const auto& child : n.children()) {
                    if (child.type() != pugi::node_element) continue;
                    const std::string kind = element_name(child);
                    opacity_only = kind == "g" || kind == "rect";
                    pending.push_back(child);
                }
            }
        }
        if (!opacity_only)
            document.warnings.push_back("drawn without its mask: <" + element_name(node) +
                                        " mask=\"" + property_of(node, "mask") + "\">");
    }

    static Contour mapped_contour(const Affine& m, std::vector<Point2> points, bool closed) {
        for (auto& p : points) p = m.apply(p);
        return Contour{std::move(points), closed};
    }

    // <rect>, its corners rounded by rx and ry.
    std::vector<Contour> rect_geometry(const pugi::xml_node& node, const Affine& m) const {
        const double tol = options.tolerance_mm;
        const double x = number_attribute(node, "x", 0), y = number_attribute(node, "y", 0);
        const double w = number_attribute(node, "width", 0),
                     h = number_attribute(node, "height", 0);
        if (w <= 0 || h <= 0) return {};
        double rx = number_attribute(node, "rx", -1), ry = number_attribute(node, "ry", -1);
        if (rx < 0) rx = ry;
        if (ry < 0) ry = rx;
        rx = std::clamp(rx, 0.0, w / 2);
        ry = std::clamp(ry, 0.0, h / 2);
        if (rx <= 0 || ry <= 0)
            return {mapped_contour(m, {{x, y}, {x + w, y}, {x + w, y + h}, {x, y + h}}, true)};
        std::vector<Point2> out{{x + rx, y}};
        const auto corner = [&](Point2 from, Point2 to) {
            out.push_back(from);
            arc_to(m, from, rx, ry, 0, false, true, to, tol, out);
        };
        // Arc points are produced in user units and mapped below with the rest.
        corner({x + w - rx, y}, {x + w, y + ry});
        corner({x + w, y + h - ry}, {x + w - rx, y + h});
        corner({x + rx, y + h}, {x, y + h - ry});
        corner({x, y + ry}, {x + rx, y});
        out.pop_back();
        return {mapped_contour(m, std::move(out), true)};
    }

    std::vector<Contour> geometry_of(const pugi::xml_node& node, const std::string& name,
                                     const Affine& m) {
        const double tol = options.tolerance_mm;
        const auto mapped = [&m](std::vector<Point2> points, bool closed) {
            return mapped_contour(m, std::move(points), closed);
        };
        if (name == "path") return parse_path_data(node.attribute("d").value(), m, tol);
        if (name == "polygon" || name == "polyline") {
            auto points = point_list(node);
            if (points.size() < 2) return {};
            return {mapped(std::move(points), name == "polygon")};
        }
        if (name == "line") {
            return {mapped({{number_attribute(node, "x1", 0), number_attribute(node, "y1", 0)},
                            {number_attribute(node, "x2", 0), number_attribute(node, "y2", 0)}},
                           false)};
        }
        if (name == "rect") return rect_geometry(node, m);
        if (name == "circle" || name == "ellipse") {
            const double cx = number_attribute(node, "cx", 0), cy = number_attribute(node, "cy", 0);
            const double rx =
                name == "circle" ? number_attribute(node, "r", 0) : number_attribute(node, "rx", 0);
            const double ry = name == "circle" ? rx : number_attribute(node, "ry", 0);
            if (rx <= 0 || ry <= 0) return {};
            std::vector<Point2> out;
            flatten_arc(m, {cx, cy}, rx, ry, 0, 0, 2 * std::numbers::pi, tol, out);
            out.pop_back();  // the last point repeats the first
            return {mapped(std::move(out), true)};
        }
        return {};  // anything else is not drawn
    }
};

}  // namespace

Affine Affine::then(const Affine& o) const {
    return {o.a * a + o.c * b, o.b * a + o.d * b,       o.a * c + o.c * d,
            o.b * c + o.d * d, o.a * e + o.c * f + o.e, o.b * e + o.d * f + o.f};
}

double Affine::scale() const {
    return std::sqrt(std::abs(a * d - b * c));
}

Affine parse_transform(std::string_view text) {
    Affine total;
    std::size_t i = 0;
    while (true) {
        while (i < text.size() &&
               (std::isspace(static_cast<unsigned char>(text[i])) || text[i] == ','))
            ++i;
        if (i >= text.size()) break;
        const auto open = text.find('(', i);
        const auto close = text.find(')', i);
        if (open == std::string_view::npos || close == std::string_view::npos || close < open) {
            throw SvgError("malformed transform \"" + std::string(text) + "\"");
        }
        const std::string name = without_spaces(std::string(text.substr(i, open - i)));
        Scanner s(text.substr(open + 1, close - open - 1));
        std::vector<double> v;
        while (!s.at_end()) {
            const auto n = s.number();
            if (!n) throw SvgError("non-numeric transform \"" + std::string(text) + "\"");
            v.push_back(*n);
        }
        const auto need = [&](std::size_t lo, std::size_t hi) {
            if (v.size() < lo || v.size() > hi)
                throw SvgError("transform " + name + "() with " + std::to_string(v.size()) +
                               " numbers");
        };
        Affine t;
        if (name == "matrix") {
            need(6, 6);
            t = {v[0], v[1], v[2], v[3], v[4], v[5]};
        } else if (name == "translate") {
            need(1, 2);
            t.e = v[0];
            t.f = v.size() > 1 ? v[1] : 0;
        } else if (name == "scale") {
            need(1, 2);
            t.a = v[0];
            t.d = v.size() > 1 ? v[1] : v[0];
        } else if (name == "rotate") {
            need(1, 3);
            if (v.size() == 2) throw SvgError("transform rotate() with 2 numbers");
            const double r = v[0] * std::numbers::pi / 180, cr = std::cos(r), sr = std::sin(r);
            const double cx = v.size() == 3 ? v[1] : 0, cy = v.size() == 3 ? v[2] : 0;
            t = {cr, sr, -sr, cr, cx - cr * cx + sr * cy, cy - sr * cx - cr * cy};
        } else if (name == "skewX") {
            need(1, 1);
            t.c = std::tan(v[0] * std::numbers::pi / 180);
        } else if (name == "skewY") {
            need(1, 1);
            t.b = std::tan(v[0] * std::numbers::pi / 180);
        } else {
            throw SvgError("unknown transform " + name + "()");
        }
        // "a b" means apply b first, then a.
        total = t.then(total);
        i = close + 1;
    }
    return total;
}

namespace {

// The document's XML, its <svg> root checked; the map from its viewport to millimetres and the
// viewport's size (0 where the document gives none).
struct LoadedSvg {
    pugi::xml_document xml;
    pugi::xml_node root;
    Affine to_mm;
    double width_mm = 0, height_mm = 0;
};

void load_svg(std::string_view text, const SvgOptions& options, LoadedSvg& loaded) {
    if (text.size() > options.max_bytes) {
        throw SvgError("the document is " + std::to_string(text.size()) +
                       " bytes, over the limit of " + std::to_string(options.max_bytes));
    }
    const auto parsed = loaded.xml.load_buffer(text.data(), text.size(), pugi::parse_default);
    if (!parsed) {
        const auto offset = static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, parsed.offset));
        const auto line =
            1 +
            std::count(text.begin(),
                       text.begin() + static_cast<std::ptrdiff_t>(std::min(offset, text.size())),
                       '\n');
        throw SvgError("malformed XML at line " + std::to_string(line) + ": " +
                       parsed.description());
    }
    const pugi::xml_node root = loaded.xml.document_element();
    if (!root || element_name(root) != "svg")
        throw SvgError("not an SVG document: no <svg> root element");
    loaded.root = root;
    // The viewport in CSS pixels, then the viewBox mapped into it (preserveAspectRatio's
    // default, xMidYMid meet).
    std::optional<double> width, height;
    if (root.attribute("width") &&
        std::string(root.attribute("width").value()).find('%') == std::string::npos) {
        width = number_attribute(root, "width", 0);
    }
    if (root.attribute("height") &&
        std::string(root.attribute("height").value()).find('%') == std::string::npos) {
        height = number_attribute(root, "height", 0);
    }
    // SVG makes a negative size an error (and a zero one draws nothing): refused, not guessed.
    for (const auto& [name, size] : {std::pair{"width", width}, std::pair{"height", height}})
        if (size && !(*size > 0))
            throw SvgError(std::string(name) + "=\"" + root.attribute(name).value() +
                           "\" on <svg>: a drawing's " + name + " must be above 0");
    Affine to_px;
    if (const auto vb = root.attribute("viewBox")) {
        Scanner s(vb.value());
        double v[4];
        for (double& x : v) {
            const auto n = s.number();
            if (!n)
                throw SvgError(std::string("non-numeric attribute viewBox=\"") + vb.value() +
                               "\" on <svg>");
            x = *n;
        }
        if (v[2] <= 0 || v[3] <= 0) throw SvgError("viewBox needs a positive width and height");
        const double w = width.value_or(v[2]), h = height.value_or(v[3]);
        const double scale = std::min(w / v[2], h / v[3]);
        to_px = {scale,
                 0,
                 0,
                 scale,
                 (w - v[2] * scale) / 2 - v[0] * scale,
                 (h - v[3] * scale) / 2 - v[1] * scale};
        width = w;
        height = h;
    }
    loaded.to_mm = to_px.then(Affine{kMmPerCssPixel, 0, 0, kMmPerCssPixel, 0, 0});
    loaded.width_mm = width.value_or(0) * kMmPerCssPixel;
    loaded.height_mm = height.value_or(0) * kMmPerCssPixel;
}

}  // namespace

SvgDocument parse_svg(std::string_view text, const SvgOptions& options) {
    LoadedSvg loaded;
    load_svg(text, options, loaded);
    Reader reader;
    reader.options = options;
    reader.index(loaded.root);
    reader.document.width_mm = loaded.width_mm;
    reader.document.height_mm = loaded.height_mm;
    const Style root_style = style_of(loaded.root, Style{}, reader.document.warnings);
    for (const auto& child : loaded.root.children()) {
        if (child.type() == pugi::node_element) reader.element(child, loaded.to_mm, root_style);
    }
    if (reader.document.shapes.empty()) throw SvgError("nothing drawable in the document");
    return std::move(reader.document);
}

SvgDocument check_svg_geometry(std::string_view text, const SvgOptions& options) {
    LoadedSvg loaded;
    load_svg(text, options, loaded);
    Reader reader;
    reader.options = options;
    reader.checking = true;
    reader.document.width_mm = loaded.width_mm;
    reader.document.height_mm = loaded.height_mm;
    const Style root_style = style_of(loaded.root, Style{}, reader.document.warnings);
    for (const auto& child : loaded.root.children()) {
        if (child.type() == pugi::node_element) reader.element(child, loaded.to_mm, root_style);
    }
    return std::move(reader.document);
}

}  // namespace calbox::drawings
