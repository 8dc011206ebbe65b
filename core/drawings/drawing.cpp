#include "core/drawings/drawing.hpp"

#include <cairo-svg.h>
#include <cairo.h>
#include <fontconfig/fontconfig.h>
#include <librsvg/rsvg.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <memory>
#include <mutex>
#include <pugixml.hpp>
#include <set>
#include <string>

#include "core/number_text.hpp"

namespace calbox::drawings {
namespace {

constexpr const char* kSvgNamespace = "http://www.w3.org/2000/svg";
// cairo keeps a path's points in 24.8 fixed point (a 256th of a device unit): the drawing is
// painted about 2048 units across, so that its points come back within a two-millionth of its
// size whatever scale the job gives it later (a 300 mm job: 0.6 um). Larger, a font grows past
// the 2400 or so pixels FreeType draws: its text is then painted again at an eighth the size.
constexpr double kPaintedUnits = 2048;
constexpr int kPaintings = 4;

struct GObjectDeleter {
    void operator()(void* object) const { g_object_unref(object); }
};
struct ErrorDeleter {
    void operator()(GError* error) const { g_error_free(error); }
};
struct SurfaceDeleter {
    void operator()(cairo_surface_t* surface) const { cairo_surface_destroy(surface); }
};
struct ContextDeleter {
    void operator()(cairo_t* context) const { cairo_destroy(context); }
};

cairo_status_t append_to_string(void* closure, const unsigned char* data, unsigned int length) {
    static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
    return CAIRO_STATUS_SUCCESS;
}

// A browser shows a file whose root is not in SVG's namespace as text: librsvg paints nothing.
void check_namespace(std::string_view text) {
    pugi::xml_document xml;
    xml.load_buffer(text.data(), text.size(), pugi::parse_default);  // parsed already: well-formed
    const auto root = xml.document_element();
    const std::string name = root.name();
    const auto colon = name.find(':');
    const std::string attribute =
        colon == std::string::npos ? "xmlns" : "xmlns:" + name.substr(0, colon);
    if (std::string(root.attribute(attribute.c_str()).value()) != kSvgNamespace)
        throw SvgError(std::string("<svg> is not in SVG's namespace: give it xmlns=\"") +
                       kSvgNamespace + "\" (a browser shows this file as text, not a drawing)");
}

// The font families a document names (attributes, style="" and <style> sheets alike), each
// list in its order: what follows `font-family=` in quotes, or `font-family:` up to the end of
// the declaration.
std::vector<std::vector<std::string>> named_font_families(std::string_view text) {
    constexpr std::string_view kProperty = "font-family";
    std::vector<std::vector<std::string>> lists;
    for (auto at = text.find(kProperty); at != std::string_view::npos;
         at = text.find(kProperty, at + 1)) {
        std::size_t i = at + kProperty.size();
        while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
        if (i >= text.size() || (text[i] != '=' && text[i] != ':')) continue;
        const bool attribute = text[i] == '=';
        ++i;
        while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
        std::string_view value;
        if (attribute) {
            if (i >= text.size() || (text[i] != '"' && text[i] != '\'')) continue;
            const auto close = text.find(text[i], i + 1);
            if (close == std::string_view::npos) continue;
            value = text.substr(i + 1, close - i - 1);
        } else {
            const auto end = text.find_first_of(";}\"<", i);
            value = text.substr(i, end == std::string_view::npos ? text.size() - i : end - i);
        }
        std::vector<std::string> list;
        std::size_t start = 0;
        while (start <= value.size()) {
            const auto comma = std::min(value.find(',', start), value.size());
            std::string name(value.substr(start, comma - start));
            const auto drop = [](unsigned char c) {
                return std::isspace(c) != 0 || c == '\'' || c == '"';
            };
            while (!name.empty() && drop(static_cast<unsigned char>(name.back()))) name.pop_back();
            while (!name.empty() && drop(static_cast<unsigned char>(name.front())))
                name.erase(0, 1);
            if (!name.empty()) list.push_back(name);
            start = comma + 1;
        }
        if (!list.empty()) lists.push_back(std::move(list));
    }
    return lists;
}

std::string lowercase(std::string text) {
    std::transform(text.begin(), text.end(), text.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return text;
}

bool generic_family(const std::string& name) {
    static const std::set<std::string> generic{"serif",   "sans-serif", "monospace", "cursive",
                                               "fantasy", "system-ui",  "inherit",   "initial"};
    return generic.count(lowercase(name)) != 0;
}

// The family fontconfig (which librsvg's text goes through) gives for a named one.
std::string family_used_for(const std::string& name) {
    FcPattern* pattern = FcPatternCreate();
    FcPatternAddString(pattern, FC_FAMILY, reinterpret_cast<const FcChar8*>(name.c_str()));
    FcConfigSubstitute(nullptr, pattern, FcMatchPattern);
    FcDefaultSubstitute(pattern);
    FcResult result = FcResultNoMatch;
    FcPattern* match = FcFontMatch(nullptr, pattern, &result);
    std::string used;
    FcChar8* family = nullptr;
    if (match != nullptr && FcPatternGetString(match, FC_FAMILY, 0, &family) == FcResultMatch)
        used = reinterpret_cast<const char*>(family);
    if (match != nullptr) FcPatternDestroy(match);
    FcPatternDestroy(pattern);
    return used;
}

// Text is drawn in the first named family the system has, as fontconfig picks it: a family that
// is not there is named, with the one used instead.
void warn_of_missing_fonts(std::string_view text, std::vector<std::string>& warnings) {
    if (text.find("<text") == std::string_view::npos &&
        text.find(":text") == std::string_view::npos)
        return;
    std::set<std::string> told;
    for (const auto& list : named_font_families(text)) {
        const std::string& first = list.front();
        if (generic_family(first) || !told.insert(lowercase(first)).second) continue;
        const std::string used = family_used_for(first);
        if (lowercase(used) == lowercase(first)) continue;
        std::string instead = used;
        for (std::size_t k = 1; k < list.size(); ++k) {
            const std::string next = family_used_for(list[k]);
            if (generic_family(list[k]) || lowercase(next) == lowercase(list[k])) {
                instead = next;
                break;
            }
        }
        std::string warning = "the font \"" + first;
        warning.append("\" is not on this system: its text is drawn in \"").append(instead);
        warnings.push_back(warning.append("\""));
    }
}

// What librsvg and the libraries under it (Pango, GLib) would print on standard error while a
// drawing is painted on this thread, kept instead: a user sees calbox's line, not theirs. GLib
// sends every message through one writer (its structured log) set once for the process; messages
// of other threads, or logged outside a painting, go on to GLib's own writer.
thread_local std::vector<std::string>* t_library_messages = nullptr;

GLogWriterOutput write_library_message(GLogLevelFlags level, const GLogField* fields, gsize count,
                                       gpointer) {
    if (t_library_messages == nullptr) return g_log_writer_default(level, fields, count, nullptr);
    std::string domain, message;
    for (gsize k = 0; k < count; ++k) {
        const std::string key = fields[k].key;
        const auto* value = static_cast<const char*>(fields[k].value);
        if (value == nullptr || fields[k].length > 0) continue;  // text fields are terminated
        if (key == "GLIB_DOMAIN") domain = value;
        if (key == "MESSAGE") message = value;
    }
    t_library_messages->push_back(domain + ": " + message);
    return G_LOG_WRITER_HANDLED;
}

class LibraryMessages {
  public:
    LibraryMessages() {
        static std::once_flag routed;
        std::call_once(routed,
                       [] { g_log_set_writer_func(write_library_message, nullptr, nullptr); });
        t_library_messages = &messages_;
    }
    ~LibraryMessages() { t_library_messages = nullptr; }
    LibraryMessages(const LibraryMessages&) = delete;
    LibraryMessages& operator=(const LibraryMessages&) = delete;
    const std::vector<std::string>& messages() const { return messages_; }
    void clear() { messages_.clear(); }

  private:
    std::vector<std::string> messages_;
};

void scale_and_shift(SvgDocument& document, double scale, geometry::Point2 shift_mm) {
    const auto map = [&](geometry::Point2& p) {
        p = {p.x * scale - shift_mm.x, p.y * scale - shift_mm.y};
    };
    for (auto& shape : document.shapes) {
        for (auto& contour : shape.contours)
            for (auto& p : contour.points) map(p);
        if (shape.clip_region)
            for (auto& polygon : *shape.clip_region)
                for (auto& p : polygon) map(p);
        shape.stroke_width_mm *= scale;
    }
}

void paint(RsvgHandle* handle, const RsvgRectangle& viewport, double width, double height,
           double scale, std::string& painted) {
    std::unique_ptr<cairo_surface_t, SurfaceDeleter> surface(cairo_svg_surface_create_for_stream(
        append_to_string, &painted, width * scale, height * scale));
    cairo_svg_surface_set_document_unit(surface.get(), CAIRO_SVG_UNIT_PX);
    std::unique_ptr<cairo_t, ContextDeleter> context(cairo_create(surface.get()));
    cairo_scale(context.get(), scale, scale);
    GError* raw_error = nullptr;
    if (!rsvg_handle_render_document(handle, context.get(), &viewport, &raw_error)) {
        std::unique_ptr<GError, ErrorDeleter> error(raw_error);
        throw SvgError(std::string("librsvg cannot paint it: ") + error->message);
    }
    context.reset();
    cairo_surface_finish(surface.get());
    if (cairo_surface_status(surface.get()) != CAIRO_STATUS_SUCCESS)
        throw SvgError(std::string("cairo cannot write what librsvg painted: ") +
                       cairo_status_to_string(cairo_surface_status(surface.get())));
}

}  // namespace

SvgDocument read_drawing(std::string_view text, const SvgOptions& options) {
    // The checks parse_svg makes, of the document as written: what librsvg would drop quietly
    // (a path cut short at a bad command, a shape whose size does not read) is refused here.
    const SvgDocument page = check_svg_geometry(text, options);
    check_namespace(text);
    GError* raw_error = nullptr;
    std::unique_ptr<RsvgHandle, GObjectDeleter> handle(rsvg_handle_new_from_data(
        reinterpret_cast<const guint8*>(text.data()), text.size(), &raw_error));
    std::unique_ptr<GError, ErrorDeleter> error(raw_error);
    if (!handle) throw SvgError(std::string("librsvg cannot read it: ") + error->message);
    rsvg_handle_set_dpi(handle.get(), 96);
    // The page as parse_svg reads it; a document without one is painted over its ink, moved
    // clear of the surface's origin and moved back after.
    const bool has_page = page.width_mm > 0 && page.height_mm > 0;
    RsvgRectangle viewport{0, 0, page.width_mm / kMmPerCssPixel, page.height_mm / kMmPerCssPixel};
    geometry::Point2 shift_px{0, 0};
    if (!has_page) {
        // Without a viewBox its user units are pixels whatever the viewport: any will measure.
        const RsvgRectangle measured{0, 0, 1000, 1000};
        RsvgRectangle ink{}, logical{};
        if (!rsvg_handle_get_geometry_for_layer(handle.get(), nullptr, &measured, &ink, &logical,
                                                &raw_error)) {
            error.reset(raw_error);
            throw SvgError(std::string("librsvg cannot measure it: ") + error->message);
        }
        shift_px = {1 - std::min(0.0, ink.x), 1 - std::min(0.0, ink.y)};
        viewport = {shift_px.x, shift_px.y, std::max(0.0, ink.x + ink.width) + shift_px.x + 1,
                    std::max(0.0, ink.y + ink.height) + shift_px.y + 1};
    }
    const double surface_w = viewport.x + viewport.width, surface_h = viewport.y + viewport.height;
    const double larger = std::max(surface_w, surface_h);
    if (!(larger > 0) || !std::isfinite(larger)) throw SvgError("nothing drawable in the document");
    double scale = std::exp2(std::floor(std::log2(kPaintedUnits / larger)));
    std::string painted;
    LibraryMessages library;
    for (int painting = 1;; ++painting) {
        painted.clear();
        library.clear();
        paint(handle.get(), viewport, surface_w, surface_h, scale, painted);
        if (library.messages().empty()) break;
        if (painting == kPaintings)
            throw SvgError("librsvg could not draw it whole, even at " + number_text("%g", scale) +
                           " of its size (" + library.messages().front() + ")");
        scale /= 8;
    }
    SvgOptions painted_options = options;
    painted_options.max_bytes = std::max(options.max_bytes, painted.size());
    painted_options.tolerance_mm = options.tolerance_mm * scale;
    SvgDocument document = parse_svg(painted, painted_options);
    scale_and_shift(document, 1 / scale,
                    {shift_px.x * kMmPerCssPixel, shift_px.y * kMmPerCssPixel});
    document.width_mm = page.width_mm;
    document.height_mm = page.height_mm;
    // Warnings of the document as written first (a styling value ignored), then of what was
    // painted (an image), each once.
    std::vector<std::string> warnings = page.warnings;
    for (auto& w : document.warnings)
        if (std::find(warnings.begin(), warnings.end(), w) == warnings.end())
            warnings.push_back(std::move(w));
    warn_of_missing_fonts(text, warnings);
    document.warnings = std::move(warnings);
    return document;
}

}  // namespace calbox::drawings
