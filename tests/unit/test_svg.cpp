// The SVG reader against areas and points worked out by hand.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <string>

#include "core/drawings/drawing.hpp"
#include "core/drawings/svg.hpp"
#include "core/jobs/job.hpp"
#include "core/jobs/toolpath.hpp"
#include "core/models/machine_file.hpp"
#include "tests/support/whole_file.hpp"

using namespace calbox;
using namespace calbox::jobs;
using namespace calbox::drawings;
using calbox::jobs::plan_svg_job;

namespace {

constexpr double kPi = 3.14159265358979323846;

double signed_area(const std::vector<geometry::Point2>& p) {
    double a = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
        const auto& u = p[i];
        const auto& v = p[(i + 1) % p.size()];
        a += u.x * v.y - v.x * u.y;
    }
    return a / 2;
}

double area_of(const std::vector<Contour>& contours) {
    double a = 0;
    for (const auto& c : contours) a += std::abs(signed_area(c.points));
    return a;
}

double region_area(const std::vector<Polygon>& region) {
    double a = 0;  // outer boundaries and holes wind opposite ways
    for (const auto& p : region) a += signed_area(p);
    return std::abs(a);
}

// A document whose user unit is one millimetre.
std::string in_mm(const std::string& body) {
    return R"svg(<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" viewBox="0 0 100 100">)svg" +
           body + "</svg>";
}

const Affine kIdentity{};

std::string error_of(const std::string& text, SvgOptions options = {}) {
    try {
        parse_svg(text, options);
    } catch (const SvgError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST_GROUP(SvgPath){};

TEST(SvgPath, half_circle_arc_has_the_area_of_half_a_disc) {
    // From (0,0) to (20,0) with radius 10, sweep 1: through (10,-10); area pi 10^2 / 2.
    const auto c = parse_path_data("M 0 0 A 10 10 0 0 1 20 0 Z", kIdentity, 0.001);
    CHECK_EQUAL(1u, c.size());
    CHECK(c[0].closed);
    DOUBLES_EQUAL(kPi * 50, area_of(c), 0.05);
    double lowest = 0;
    for (const auto& p : c[0].points) lowest = std::min(lowest, p.y);
    DOUBLES_EQUAL(-10, lowest, 0.002);
    // The other sweep goes through (10, 10); the large-arc flag changes nothing on a half circle.
    double highest = 0;
    const auto other = parse_path_data("M0,0a10,10 0 1,0 20,0z", kIdentity, 0.001);
    for (const auto& p : other[0].points) highest = std::max(highest, p.y);
    DOUBLES_EQUAL(10, highest, 0.002);
}

TEST(SvgPath, arc_with_radii_too_small_is_scaled_up_as_the_spec_says) {
    // Radius 1 between points 20 apart becomes radius 10: a half circle again.
    DOUBLES_EQUAL(kPi * 50, area_of(parse_path_data("M 0 0 A 1 1 0 0 1 20 0 Z", kIdentity, 0.001)),
                  0.05);
}

TEST(SvgPath, cubic_and_quadratic_curves_enclose_their_hand_worked_areas) {
    // Cubic (0,0) (0,10) (10,10) (10,0) with its chord: 60 (3/20 of the control determinant sum).
    DOUBLES_EQUAL(60.0, area_of(parse_path_data("M0 0 C 0 10 10 10 10 0 Z", kIdentity, 0.001)),
                  0.02);
    // Parabolic segment: 2/3 of base 10 times peak height 5.
    DOUBLES_EQUAL(200.0 / 6, area_of(parse_path_data("M0 0 Q 5 10 10 0 Z", kIdentity, 0.001)),
                  0.02);
    // Relative forms of the same.
    DOUBLES_EQUAL(60.0, area_of(parse_path_data("m0 0 c 0 10 10 10 10 0 z", kIdentity, 0.001)),
                  0.02);
    DOUBLES_EQUAL(200.0 / 6, area_of(parse_path_data("m0 0 q 5 10 10 0 z", kIdentity, 0.001)),
                  0.02);
}

TEST(SvgPath, smooth_curves_reflect_the_previous_control_point) {
    // T after Q reflects (5,10) about (10,0) to (15,-10): the midpoint of the second curve is
    // (15,-5).
    const auto t = parse_path_data("M0 0 Q 5 10 10 0 T 20 0", kIdentity, 0.0001);
    bool found = false;
    for (const auto& p : t[0].points)
        found |= std::abs(p.x - 15) < 0.01 && std::abs(p.y + 5) < 0.01;
    CHECK(found);
    // S after C reflects (10,10) about (10,0) to (10,-10): the second curve mirrors the first.
    const auto s = parse_path_data("M0 0 C 0 10 10 10 10 0 S 20 -10 20 0", kIdentity, 0.0001);
    double lowest = 0;
    for (const auto& p : s[0].points) lowest = std::min(lowest, p.y);
    DOUBLES_EQUAL(-7.5, lowest, 0.001);  // a cubic with controls at height 10 peaks at 3/4 of it
}

TEST(SvgPath, relative_lines_and_implicit_repeats) {
    const auto square = parse_path_data("m 10 10 h 10 v 10 h -10 z", kIdentity, 0.01);
    DOUBLES_EQUAL(100, area_of(square), 1e-9);
    DOUBLES_EQUAL(10, square[0].points[0].x, 0);
    // Pairs after M are lines; numbers run together as SVG allows ("-5-5", ".5.5").
    const auto run = parse_path_data("M0,0 10,0 10,10L0,10Z m1 1 .5.5-5-5", kIdentity, 0.01);
    CHECK_EQUAL(2u, run.size());
    DOUBLES_EQUAL(100, std::abs(signed_area(run[0].points)), 1e-9);
    DOUBLES_EQUAL(-3.5, run[1].points.back().x, 1e-9);  // 0+1 then +.5 then -5
}

TEST(SvgPath, unknown_commands_and_bad_numbers_are_refused) {
    CHECK_THROWS(SvgError, parse_path_data("M0 0 X 10 10", kIdentity, 0.01));
    CHECK_THROWS(SvgError, parse_path_data("M0 0 L 10", kIdentity, 0.01));
    CHECK_THROWS(SvgError, parse_path_data("10 10", kIdentity, 0.01));
    CHECK_THROWS(SvgError, parse_path_data("M0 0 A 5 5 0 2 1 10 0", kIdentity, 0.01));
    // Found by tests/fuzz under UBSan: an arc between points 1e85 apart counted its points
    // past int. Refused by name; a 10 m arc is still drawn.
    try {
        parse_path_data("M0 0 A 3 4 20 1 0 1e85 0", kIdentity, 0.01);
        FAIL("flattened");
    } catch (const SvgError& e) {
        STRCMP_CONTAINS("is too large to flatten", e.what());
    }
    CHECK(parse_path_data("M0 0 A 5000 5000 0 0 1 10000 0", kIdentity, 0.01).size() >= 1);
}

TEST_GROUP(SvgDocument){};

TEST(SvgDocument, nested_transforms_map_a_rectangle_where_worked_out_by_hand) {
    // rect (1,1)-(3,4), rotate(90): (x,y) -> (-y,x), scale(2), translate(10,0):
    // corners (8,2) (8,6) (2,6) (2,2).
    const auto doc = parse_svg(
        in_mm(R"svg(<g transform="translate(10,0)"><g transform="scale(2)">)svg"
              R"svg(<rect x="1" y="1" width="2" height="3" transform="rotate(90)"/></g></g>)svg"));
    CHECK_EQUAL(1u, doc.shapes.size());
    const auto& p = doc.shapes[0].contours[0].points;
    CHECK_EQUAL(4u, p.size());
    const geometry::Point2 expected[4] = {{8, 2}, {8, 6}, {2, 6}, {2, 2}};
    for (int i = 0; i < 4; ++i) {
        DOUBLES_EQUAL(expected[i].x, p[static_cast<std::size_t>(i)].x, 1e-9);
        DOUBLES_EQUAL(expected[i].y, p[static_cast<std::size_t>(i)].y, 1e-9);
    }
}

TEST(SvgDocument, units_viewbox_and_pixels) {
    // No viewBox: a unitless length is a CSS pixel, 25.4/96 mm.
    const auto px =
        parse_svg(R"svg(<svg width="96" height="96"><rect width="96" height="48"/></svg>)svg");
    DOUBLES_EQUAL(25.4 * 12.7, area_of(px.shapes[0].contours), 1e-6);
    DOUBLES_EQUAL(25.4, px.width_mm, 1e-9);
    // viewBox 0 0 80 40 in 40 x 20 mm: half a millimetre a unit, the origin shifted.
    const auto vb = parse_svg(
        R"svg(<svg width="40mm" height="20mm" viewBox="10 10 80 40"><circle cx="50" cy="30" r="10"/></svg>)svg");
    DOUBLES_EQUAL(kPi * 25, area_of(vb.shapes[0].contours), 0.005 * 2 * kPi * 5);
    double xmin = 1e9;
    for (const auto& q : vb.shapes[0].contours[0].points) xmin = std::min(xmin, q.x);
    DOUBLES_EQUAL(15, xmin, 0.005);  // (50 - 10 - 10) * 0.5, within the flattening tolerance
    // Other units: 1in = 25.4 mm, 72pt = 1in, 1cm = 10mm.
    DOUBLES_EQUAL(
        25.4,
        parse_svg(
            R"svg(<svg width="1in" height="72pt" viewBox="0 0 1 1"><rect width="1" height="1"/></svg>)svg")
            .width_mm,
        1e-9);
}

TEST(SvgDocument, shapes_styles_and_fill_rules) {
    const auto doc = parse_svg(in_mm(
        R"svg(<ellipse cx="0" cy="0" rx="4" ry="2"/>)svg"
        R"svg(<line x1="0" y1="0" x2="10" y2="0" stroke="black"/>)svg"
        R"svg(<polyline points="0,0 5,0 5,5" style="fill:none;stroke:#000;stroke-width:0.4"/>)svg"
        R"svg(<rect width="10" height="10" rx="2" fill-rule="evenodd"/>)svg"
        R"svg(<path d="M0 0 H5" fill="none"/>)svg"
        R"svg(<g style="display:none"><rect width="5" height="5"/></g>)svg"));
    CHECK_EQUAL(
        4u, doc.shapes.size());  // the unstroked unfilled path and the hidden group draw nothing
    DOUBLES_EQUAL(kPi * 8, area_of(doc.shapes[0].contours), 0.005 * 20);
    CHECK_FALSE(doc.shapes[1].filled);
    CHECK(doc.shapes[1].stroked);
    CHECK_FALSE(doc.shapes[2].filled);
    DOUBLES_EQUAL(0.4, doc.shapes[2].stroke_width_mm, 1e-9);
    CHECK(doc.shapes[3].fill_rule == FillRule::evenodd);
    // A 10 mm square with 2 mm rounded corners: 100 - (4 - pi) * 4.
    DOUBLES_EQUAL(100 - (4 - kPi) * 4, area_of(doc.shapes[3].contours), 0.005 * 2 * kPi * 2);
}

TEST(SvgDocument, ring_and_star_fill_by_rule) {
    // Two circles in one path, drawn the same way round: nonzero fills the hole, evenodd not.
    const auto ring =
        parse_svg(in_mm(R"svg(<path d="M -10 0 A 10 10 0 1 0 10 0 A 10 10 0 1 0 -10 0 Z )svg"
                        R"svg(M -5 0 A 5 5 0 1 0 5 0 A 5 5 0 1 0 -5 0 Z"/>)svg"));
    const auto& contours = ring.shapes[0].contours;
    // Flattened within 0.005 mm, a polygon loses at most that times its perimeter.
    DOUBLES_EQUAL(kPi * 100, region_area(resolve_fill(contours, FillRule::nonzero)),
                  0.005 * 2 * kPi * 10);
    DOUBLES_EQUAL(kPi * 75, region_area(resolve_fill(contours, FillRule::evenodd)),
                  0.005 * 2 * kPi * 15);
    // A pentagram, outer radius 10: the centre pentagon (inner radius 10 cos72/cos36) is filled
    // under nonzero only: 5 R r sin36 = 112.257 against 112.257 - 2.5 r^2 sin72 = 77.568.
    const auto star = parse_svg(in_mm(
        R"svg(<polygon points="0,-10 -5.877853,8.090170 9.510565,-3.090170 -9.510565,-3.090170 5.877853,8.090170"/>)svg"));
    DOUBLES_EQUAL(112.257, region_area(resolve_fill(star.shapes[0].contours, FillRule::nonzero)),
                  0.01);
    DOUBLES_EQUAL(77.568, region_area(resolve_fill(star.shapes[0].contours, FillRule::evenodd)),
                  0.01);
}

TEST(SvgDocument, bad_documents_get_one_line_naming_the_problem) {
    STRCMP_CONTAINS("malformed XML at line 3",
                    error_of("<svg>\n<rect width='1' height='1'>\n</svg>").c_str());
    STRCMP_CONTAINS("no <svg> root", error_of("<html><rect width='1' height='1'/></html>").c_str());
    STRCMP_CONTAINS("nothing drawable",
                    error_of("<svg xmlns='http://www.w3.org/2000/svg'></svg>").c_str());
    // Text is refused naming the element (a browser shows it; a machine needs its outlines).
    STRCMP_CONTAINS("<text> is not drawn by a machine: convert text to paths",
                    error_of("<svg><text>hello</text></svg>").c_str());
    // A geometry value that does not parse is refused; a styling value is ignored with a
    // warning, as a browser ignores it.
    const auto styled =
        parse_svg(in_mm("<path d='M0 0 L5 0' stroke='#000' stroke-width='0.35 px'/>"));
    CHECK_EQUAL(1u, styled.warnings.size());
    STRCMP_CONTAINS("ignored stroke-width \"0.35 px\" on <path>", styled.warnings[0].c_str());
    CHECK(styled.shapes[0].stroked);
    // Groups nested 10,000 deep: refused in one line, not a stack overflow.
    std::string deep;
    for (int i = 0; i < 10000; ++i) deep += "<g>";
    deep += "<rect width='1' height='1'/>";
    for (int i = 0; i < 10000; ++i) deep += "</g>";
    STRCMP_CONTAINS("groups nested deeper than 256 levels", error_of(in_mm(deep)).c_str());
    STRCMP_CONTAINS("unknown command 'X'", error_of(in_mm("<path d='M0 0 X 5 5'/>")).c_str());
    STRCMP_CONTAINS("non-numeric attribute width=\"abc\" on <rect>",
                    error_of(in_mm("<rect width='abc' height='2'/>")).c_str());
    STRCMP_CONTAINS("non-numeric attribute points",
                    error_of(in_mm("<polygon points='0,0 1,x 2,2'/>")).c_str());
    SvgOptions small;
    small.max_bytes = 100;
    STRCMP_CONTAINS("over the limit of 100",
                    error_of(in_mm("<rect width='2' height='2'/>"), small).c_str());
    STRCMP_CONTAINS("unknown transform",
                    error_of(in_mm("<rect width='2' height='2' transform='spin(3)'/>")).c_str());
    STRCMP_EQUAL("", error_of("").empty() ? "x" : "");  // an empty string is malformed too
}

// Lines cut at a page's edge (a stroke past the page, as a browser shows it), worked by hand.
TEST_GROUP(PageCut){};

TEST(PageCut, lines_past_the_window_are_cut_at_its_edge) {
    const std::vector<Polygon> page{{{0, 0}, {10, 0}, {10, 10}, {0, 10}}};
    // Across the page: the part between its sides.
    auto pieces = intersect_lines({Contour{{{-5, 5}, {15, 5}}, false}}, page);
    CHECK_EQUAL(1u, pieces.size());
    CHECK_EQUAL(2u, pieces[0].points.size());
    DOUBLES_EQUAL(0, std::min(pieces[0].points[0].x, pieces[0].points[1].x), 1e-9);
    DOUBLES_EQUAL(10, std::max(pieces[0].points[0].x, pieces[0].points[1].x), 1e-9);
    DOUBLES_EQUAL(5, pieces[0].points[0].y, 1e-9);
    // Wholly off the page: nothing.
    CHECK(intersect_lines({Contour{{{-5, -5}, {-1, -1}}, false}}, page).empty());
    // A closed square from (5, 5) to (15, 15): its closing side counts; inside the page lie the
    // two sides meeting at (5, 5), 5 mm each.
    pieces = intersect_lines({Contour{{{5, 5}, {15, 5}, {15, 15}, {5, 15}}, true}}, page);
    double length = 0;
    for (const auto& piece : pieces)
        for (std::size_t k = 1; k < piece.points.size(); ++k)
            length += std::hypot(piece.points[k].x - piece.points[k - 1].x,
                                 piece.points[k].y - piece.points[k - 1].y);
    DOUBLES_EQUAL(10, length, 1e-6);
    for (const auto& piece : pieces) CHECK(!piece.closed);
}

// Drawings as people make them, read through librsvg (core/drawings/drawing): what a browser
// paints, worked out by hand. Issue "Figures and drawings that mean what they say".
TEST_GROUP(Drawing){};

namespace {

std::string drawing_error(const std::string& text) {
    try {
        read_drawing(text);
    } catch (const SvgError& e) {
        return e.what();
    }
    return "";
}

// The length of every stroke's lines, in millimetres.
double stroked_length(const SvgDocument& document) {
    double length = 0;
    for (const auto& shape : document.shapes) {
        if (!shape.stroked) continue;
        for (const auto& c : shape.contours) {
            for (std::size_t k = 1; k < c.points.size(); ++k)
                length += std::hypot(c.points[k].x - c.points[k - 1].x,
                                     c.points[k].y - c.points[k - 1].y);
            if (c.closed && c.points.size() > 2)
                length += std::hypot(c.points.front().x - c.points.back().x,
                                     c.points.front().y - c.points.back().y);
        }
    }
    return length;
}

double filled_area(const SvgDocument& document) {
    double area = 0;
    for (const auto& shape : document.shapes)
        if (shape.filled) area += region_area(resolve_fill(shape.contours, shape.fill_rule));
    return area;
}

// The example diode laser (examples/laser.toml): 200 x 200 mm, 0.1 mm spot.
models::MachineFile example_laser() {
    return models::parse_machine_file(
        test::read_whole_file(std::string(CALBOX_SOURCE_DIR) + "/examples/laser.toml"),
        "laser.toml");
}

}  // namespace

TEST(Drawing, an_outline_styled_by_a_css_class_is_an_outline) {
    // Illustrator's way: the style in a sheet, the shape naming its class. An 80 mm square
    // outline, 70 mm inside the page's margin: 280 mm of line and nothing filled.
    const auto doc = read_drawing(
        in_mm("<defs><style>.cls-1{fill:none;stroke:#000;stroke-miterlimit:10;stroke-width:0.5px}"
              "</style></defs><rect class='cls-1' x='15' y='15' width='70' height='70'/>"));
    CHECK_EQUAL(1u, doc.shapes.size());
    CHECK(!doc.shapes[0].filled);
    CHECK(doc.shapes[0].stroked);
    DOUBLES_EQUAL(280, stroked_length(doc), 0.01);
    DOUBLES_EQUAL(0.5, doc.shapes[0].stroke_width_mm, 1e-3);  // 0.5 user units, 1 mm each
    const auto job = plan_svg_job(doc, example_laser(), {});
    DOUBLES_EQUAL(280, job.toolpath.working_length_mm(), 0.01);
    // The same style in style="" reads the same (parse_svg's own reading, unchanged).
    const auto plain = parse_svg(
        in_mm("<rect style='fill:none;stroke:#000;stroke-width:0.5' x='15' y='15' width='70' "
              "height='70'/>"));
    DOUBLES_EQUAL(280, stroked_length(plain), 1e-9);
    // Selectors and inheritance: an id rule beats a class rule; a group's fill is inherited.
    const auto cascade =
        read_drawing(in_mm("<style>#a{fill:none;stroke:red} .b{fill:blue} g.c{fill:none}</style>"
                           "<rect id='a' class='b' width='10' height='10'/>"
                           "<g class='c' stroke='black'><circle cx='50' cy='50' r='10'/></g>"));
    CHECK_EQUAL(2u, cascade.shapes.size());
    DOUBLES_EQUAL(0, filled_area(cascade), 1e-9);
    DOUBLES_EQUAL(40 + 2 * kPi * 10, stroked_length(cascade), 0.01);
}

TEST(Drawing, reused_shapes_and_symbols_are_drawn_where_used) {
    // Two rectangles reused at 30 and 60 mm right of a drawn one, and a circle's symbol twice:
    // three 10 x 5 mm rectangles and two discs of radius 4.
    const auto doc =
        read_drawing(in_mm("<defs><symbol id='dot'><circle cx='5' cy='5' r='4'/></symbol></defs>"
                           "<rect id='r' x='0' y='0' width='10' height='5'/>"
                           "<use href='#r' x='30'/><use xlink:href='#r' x='60' "
                           "xmlns:xlink='http://www.w3.org/1999/xlink'/>"
                           "<use href='#dot' x='10' y='50'/><use href='#dot' x='70' y='50'/>"));
    // Each disc's outline flattened to within 0.005 mm of the circle: under 0.1 mm^2 lost from it.
    DOUBLES_EQUAL(3 * 50 + 2 * kPi * 16 - 0.1, filled_area(doc), 0.1);
    double right = 0;
    for (const auto& shape : doc.shapes)
        for (const auto& c : shape.contours)
            for (const auto& p : c.points) right = std::max(right, p.x);
    DOUBLES_EQUAL(79, right, 1e-3);  // the second dot's right edge: 70 + 5 + 4
    // parse_svg reads <use> of plain geometry the same way.
    DOUBLES_EQUAL(3 * 50,
                  filled_area(parse_svg(in_mm("<rect id='r' width='10' height='5'/>"
                                              "<use href='#r' x='30'/>"
                                              "<use href='#r' x='60'/>"))),
                  1e-9);
}

TEST(Drawing, text_is_drawn_in_the_font_it_names_and_a_missing_font_is_named) {
    // Two fonts the system has (fonts-dejavu-core): the same word is wider in the serif face,
    // and both are drawn as filled outlines within the line's height.
    const auto width_of = [](const std::string& family) {
        const auto doc = read_drawing(
            in_mm("<text x='10' y='50' font-size='10' font-family='" + family + "'>Calbox</text>"));
        CHECK(doc.warnings.empty());
        CHECK(filled_area(doc) > 20);
        double left = 1e9, right = -1e9, top = 1e9, bottom = -1e9;
        for (const auto& shape : doc.shapes)
            for (const auto& c : shape.contours)
                for (const auto& p : c.points) {
                    left = std::min(left, p.x), right = std::max(right, p.x);
                    top = std::min(top, p.y), bottom = std::max(bottom, p.y);
                }
        CHECK(left >= 10 && left < 11.5);
        CHECK(bottom <= 50.5 && top >= 40);  // cap height under the font size
        return right - left;
    };
    const double sans = width_of("DejaVu Sans"), serif = width_of("DejaVu Serif");
    CHECK_TEXT(sans > 30 && sans < 45, std::to_string(sans).c_str());
    CHECK_TEXT(serif > sans + 1, (std::to_string(serif) + " vs " + std::to_string(sans)).c_str());
    const auto missing =
        read_drawing(in_mm("<style>.t{font-family:'No Such Face',sans-serif;font-size:8px}</style>"
                           "<text class='t' x='10' y='50'>A</text>"));
    CHECK_EQUAL(1u, missing.warnings.size());
    STRCMP_CONTAINS(
        "the font \"No Such Face\" is not on this system: its text is drawn in \"DejaVu",
        missing.warnings[0].c_str());
}

TEST(Drawing, a_clip_path_cuts_strokes_and_fills_where_it_ends) {
    // A 100 mm diagonal line and a 40 mm square under a clip of the page's left half: 50 mm of
    // the line's run (62.5 mm of its slope) and half of the square are drawn.
    const auto doc = read_drawing(
        in_mm("<defs><clipPath id='left'><rect width='50' height='100'/></clipPath></defs>"
              "<g clip-path='url(#left)'><line x1='0' y1='0' x2='100' y2='75' stroke='black'/>"
              "<rect x='30' y='60' width='40' height='40'/></g>"));
    for (const auto& shape : doc.shapes) {
        CHECK(shape.clip_region.has_value());
        if (shape.stroked) {
            SvgDocument one;
            one.shapes.push_back(shape);
            one.shapes.back().contours = intersect_lines(shape.contours, *shape.clip_region);
            DOUBLES_EQUAL(62.5, stroked_length(one), 0.01);
        }
        if (shape.filled && shape.element == "path" && area_of(shape.contours) > 1000) {
            DOUBLES_EQUAL(800,
                          region_area(intersect_region(
                              resolve_fill(shape.contours, shape.fill_rule), *shape.clip_region)),
                          0.01);
        }
    }
    // The job spans what shows: from the line's start to the clip's edge, 50 mm.
    const auto job = plan_svg_job(doc, example_laser(), {});
    DOUBLES_EQUAL(50, job.max_x - job.min_x, 0.01);
}

TEST(Drawing, what_would_be_dropped_quietly_is_refused_in_one_line) {
    // A browser draws a path up to a bad command and leaves a shape of unreadable size out.
    STRCMP_CONTAINS("unknown command 'X'",
                    drawing_error(in_mm("<path d='M0 0 L10 0 X 5 5' stroke='black'/>")).c_str());
    STRCMP_CONTAINS("non-numeric attribute width=\"abc\" on <rect>",
                    drawing_error(in_mm("<defs><rect id='r' width='abc' height='2'/></defs>"
                                        "<use href='#r'/>"))
                        .c_str());
    STRCMP_CONTAINS(
        "not in SVG's namespace",
        drawing_error("<svg width='10' height='10'><rect width='5' height='5'/></svg>").c_str());
    STRCMP_CONTAINS("malformed XML at line 2", drawing_error("<svg>\n<rect></svg>").c_str());
    STRCMP_CONTAINS("nothing drawable", drawing_error(in_mm("")).c_str());
    // Text once refused is drawn now.
    CHECK_EQUAL(std::string(), drawing_error(in_mm("<text x='5' y='20'>calbox</text>")));
}

TEST(Drawing, a_font_too_large_to_draw_at_first_is_drawn_again_smaller) {
    // A letter as tall as its page: painted ~2048 px across, the font would pass FreeType's
    // limit; the text is painted again at an eighth, and comes out whole, nothing printed.
    const auto doc =
        read_drawing(R"svg(<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100">)svg"
                     "<text x='0' y='95' font-size='300' font-family='DejaVu Sans'>I</text></svg>");
    CHECK(doc.warnings.empty());
    double top = 1e9, bottom = -1e9;
    for (const auto& shape : doc.shapes)
        for (const auto& c : shape.contours)
            for (const auto& p : c.points) top = std::min(top, p.y), bottom = std::max(bottom, p.y);
    // DejaVu Sans' capital I: from the baseline up 0.729 of the em (300 px), in millimetres.
    DOUBLES_EQUAL(0.729 * 300 * 25.4 / 96, bottom - top, 0.5);
}
