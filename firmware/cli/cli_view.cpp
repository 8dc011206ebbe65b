// calbox view bed: a photo of the bed seen in the machine's coordinates.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "core/modes/bed_view.hpp"
#include "core/modes/registration.hpp"
#include "core/modes/stock.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/cli_images.hpp"

namespace calbox::cli {
namespace {

// "X0,Y0,X1,Y1": the area's corners in machine millimetres.
void read_area(const std::string& text, modes::BedViewRequest& request) {
    std::vector<double> values;
    const char* at = text.data();
    const char* end = text.data() + text.size();
    while (at < end) {
        double v = 0;
        const auto [next, error] = std::from_chars(at, end, v);
        if (error != std::errc{} || !std::isfinite(v)) break;
        values.push_back(v);
        at = next;
        if (at < end && *at == ',')
            ++at;
        else
            break;
    }
    if (at != end || values.size() != 4)
        throw UsageError("--area '" + text + "': give X0,Y0,X1,Y1 in machine millimetres",
                         "calbox view bed");
    request.min_x_mm = std::min(values[0], values[2]);
    request.max_x_mm = std::max(values[0], values[2]);
    request.min_y_mm = std::min(values[1], values[3]);
    request.max_y_mm = std::max(values[1], values[3]);
}

// What every view reads: the camera, the plane, the planar result in force and the photo.
struct ViewInputs {
    geometry::CameraModel camera;
    geometry::BedPlane plane;
    std::string result_name;
    modes::PlanarSolution solution;
    std::string photo_name;
    cv::Mat photo;
};

ViewInputs read_view_inputs(const Args& args) {
    ViewInputs in;
    in.camera =
        geometry::camera_from_yaml(read_input_file(args.require("--camera"), "camera file"));
    in.plane = geometry::plane_from_yaml(read_input_file(args.require("--plane"), "plane file"));
    in.result_name = args.require("--result");
    in.solution =
        modes::planar_result_from_json(read_input_file(in.result_name, "result"), in.result_name);
    in.photo_name = args.positional()[0];
    in.photo = load_gray_image(in.photo_name);
    return in;
}

// --mm-per-px: the view's scale, 0 (the photo's own) when not given.
double view_scale(const Args& args, const std::string& command) {
    const double mm_per_px = args.number("--mm-per-px", 0);
    if (args.get("--mm-per-px") && !(mm_per_px > 0))
        throw UsageError("--mm-per-px must be above 0", command);
    return mm_per_px;
}

int view_bed(const Args& args) {
    const std::string out = args.require("-o");
    if (out.size() < 5 || out.substr(out.size() - 4) != ".png")
        throw UsageError("-o must name a .png (its world file is written beside it as .pgw)",
                         "calbox view bed");
    const std::string world = out.substr(0, out.size() - 4) + ".pgw";
    modes::BedViewRequest request;
    request.surface_height_mm = args.number("--stock-thickness", 0);
    request.mm_per_px = view_scale(args, "calbox view bed");
    if (const auto area = args.get("--area")) read_area(*area, request);
    const ViewInputs in = read_view_inputs(args);
    modes::BedView view;
    try {
        view = modes::render_bed_view(in.camera, in.plane, view_of(in.photo), in.solution, request,
                                      in.result_name);
    } catch (const modes::BedViewError& e) {
        throw std::runtime_error(in.photo_name + ": " + e.what());
    }
    cv::Mat picture;
    if (args.flag("--plain")) {
        picture = cv::Mat(view.pixels.height_px, view.pixels.width_px, CV_8UC1,
                          view.pixels.pixels.data());
    } else {
        auto colour = modes::bed_view_with_overlay(view, in.solution);
        picture =
            cv::Mat(view.pixels.height_px, view.pixels.width_px, CV_8UC3, colour.data()).clone();
    }
    write_png(out, picture);
    write_output_file(world, modes::world_file_text(view));
    std::printf(
        "%s: %d x %d px of X %.3f..%.3f Y %.3f..%.3f mm at %.3f mm a pixel (the photo's own "
        "%.3f mm there), %.3f mm above the bed, %.0f %% of it seen; +/-%.3f mm (2 sigma); world "
        "file %s\n",
        out.c_str(), view.pixels.width_px, view.pixels.height_px, view.min_x_mm, view.max_x_mm,
        view.min_y_mm, view.max_y_mm, view.mm_per_px, view.camera_mm_per_px, view.surface_height_mm,
        100 * view.seen_share, view.accuracy_mm, world.c_str());
    return 0;
}

int view_stock(const Args& args) {
    const std::string out = args.require("-o");
    const auto overlay = args.get("--overlay");
    if (overlay && (overlay->size() < 5 || overlay->substr(overlay->size() - 4) != ".png"))
        throw UsageError("--overlay must name a .png", "calbox view stock");
    const double top_mm = args.number("--stock-thickness", 0);
    const ViewInputs in = read_view_inputs(args);
    modes::StockOutline stock;
    try {
        stock = modes::find_stock(in.camera, in.plane, view_of(in.photo), in.solution, top_mm,
                                  in.result_name);
    } catch (const modes::StockError& e) {
        throw std::runtime_error(in.photo_name + ": " + e.what());
    } catch (const modes::BedViewError& e) {
        throw std::runtime_error(in.photo_name + ": " + e.what());
    }
    write_output_file(out, modes::stock_to_json(stock, in.solution.machine_fingerprint));
    if (overlay) {
        modes::BedViewRequest request;
        request.surface_height_mm = top_mm;
        request.mm_per_px = view_scale(args, "calbox view stock");
        const auto view = modes::render_bed_view(in.camera, in.plane, view_of(in.photo),
                                                 in.solution, request, in.result_name);
        auto colour = modes::bed_view_with_stock(view, in.solution, stock);
        write_png(*overlay,
                  cv::Mat(view.pixels.height_px, view.pixels.width_px, CV_8UC3, colour.data()));
    }
    std::printf(
        "%s: a %s sheet %.2f x %.2f mm turned %.3f deg (+/-%.3f), its top %.3f mm above the bed; "
        "edge points %d, %d, %d, %d (front, right, back, left), %d set aside, %d under glare\n",
        out.c_str(), stock.lighter_than_bed ? "light" : "dark", stock.width_mm, stock.depth_mm,
        stock.rotation_deg, stock.rotation_sigma_deg, stock.surface_height_mm, stock.edge_points[0],
        stock.edge_points[1], stock.edge_points[2], stock.edge_points[3],
        stock.edge_points_set_aside, stock.edge_points_under_glare);
    for (const auto& c : stock.corners)
        std::printf("%-11s X%.3f Y%.3f mm +/-%.3f (1 sigma)\n", c.name.c_str(), c.machine_mm.x,
                    c.machine_mm.y, c.sigma_mm);
    return 0;
}

// "X,Y;X,Y;X,Y[;X,Y]": the marks' places in the drawing, millimetres; for markers each is
// "ID:X,Y", its id first.
void read_marks(const std::string& text, modes::RegistrationRequest& request) {
    auto& marks = request.marks_drawing_mm;
    const bool ids = request.kind == modes::MarkKind::markers;
    std::size_t start = 0;
    while (start <= text.size()) {
        const auto end = std::min(text.find(';', start), text.size());
        std::string entry = text.substr(start, end - start);
        if (ids) {
            const auto colon = entry.find(':');
            int id = -1;
            const auto [next, error] = std::from_chars(entry.data(), entry.data() + colon, id);
            if (colon == std::string::npos || error != std::errc{} ||
                next != entry.data() + colon || id < 0)
                throw UsageError("--marks '" + text +
                                     "': give each marker as ID:X,Y (its id, then its centre in "
                                     "the drawing, mm), separated by ';'",
                                 "calbox view marks");
            request.marker_ids.push_back(id);
            entry = entry.substr(colon + 1);
        }
        const auto comma = entry.find(',');
        double x = 0, y = 0;
        const auto parse = [](const std::string& t, double& v) {
            const auto [next, error] = std::from_chars(t.data(), t.data() + t.size(), v);
            return error == std::errc{} && next == t.data() + t.size() && std::isfinite(v);
        };
        if (comma == std::string::npos || !parse(entry.substr(0, comma), x) ||
            !parse(entry.substr(comma + 1), y))
            throw UsageError("--marks '" + text +
                                 "': give each mark's X,Y in the drawing, millimetres, separated "
                                 "by ';'",
                             "calbox view marks");
        marks.push_back({x, y});
        start = end + 1;
    }
}

int view_marks(const Args& args) {
    const std::string out = args.require("-o");
    modes::RegistrationRequest request;
    const std::string kind = args.get("--mark-kind").value_or("circles");
    if (kind == "markers") {
        request.kind = modes::MarkKind::markers;
        request.dictionary = args.get("--dict").value_or("DICT_4X4_50");
    } else if (kind != "circles" && kind != "crosses") {
        throw UsageError("--mark-kind must be circles, crosses or markers, not '" + kind + "'",
                         "calbox view marks");
    } else if (args.get("--dict")) {
        throw UsageError("--dict goes with --mark-kind markers", "calbox view marks");
    }
    if (kind == "crosses") request.kind = modes::MarkKind::crosses;
    if (args.get("--mark-line") && kind != "crosses")
        throw UsageError("--mark-line goes with --mark-kind crosses", "calbox view marks");
    request.cross_line_mm = args.number("--mark-line", 0.5);
    read_marks(args.require("--marks"), request);
    request.mark_diameter_mm = args.number("--mark-diameter", 5);
    request.surface_height_mm = args.number("--stock-thickness", 0);
    request.max_residual_mm = args.number("--max-residual", 0.1);
    if (!(request.max_residual_mm > 0))
        throw UsageError("--max-residual must be above 0", "calbox view marks");
    const ViewInputs in = read_view_inputs(args);
    modes::Registration found;
    try {
        found = modes::register_marks(in.camera, in.plane, view_of(in.photo), in.solution, request,
                                      in.result_name);
    } catch (const modes::RegistrationError& e) {
        throw std::runtime_error(in.photo_name + ": " + e.what());
    } catch (const modes::BedViewError& e) {
        throw std::runtime_error(in.photo_name + ": " + e.what());
    }
    write_output_file(out, modes::registration_to_json(found, in.solution.machine_fingerprint));
    std::printf(
        "%s: the drawing's zero at machine X%.3f Y%.3f mm, turned %.3f deg, scale %.5f (%s), "
        "worst mark %.3f mm\n",
        out.c_str(), found.origin_mm.x, found.origin_mm.y, found.rotation_deg, found.scale,
        found.scale_fitted ? "fitted from four marks" : "held: three marks",
        found.worst_residual_mm);
    for (std::size_t i = 0; i < found.marks.size(); ++i) {
        const auto& m = found.marks[i];
        std::printf(
            "mark %zu: drawing X%.3f Y%.3f at machine X%.3f Y%.3f, %.3f mm off the fit "
            "(+/-%.3f)\n",
            i + 1, m.drawing_mm.x, m.drawing_mm.y, m.machine_mm.x, m.machine_mm.y, m.residual_mm,
            m.sigma_mm);
    }
    return 0;
}

}  // namespace

std::vector<Command> view_commands() {
    return {
        {"view bed",
         "the bed in the machine's coordinates, from a photo",
         {{"--camera", "camera.yaml", "the camera's calibration", Given::required},
          {"--plane", "plane.yaml", "the bed plane", Given::required},
          {"--result", "result.json", "the planar result in force (calbox solve planar)",
           Given::required},
          {"IMAGE", "", "a photo from the same camera on its mount", Given::word},
          {"-o", "bed.png", "the view, written, and its world file beside it (bed.pgw)",
           Given::required},
          {"--stock-thickness", "MM",
           "the height of what is seen above the bed (the stock's top; default 0, the bed)"},
          {"--mm-per-px", "MM", "the view's scale (default: the photo's own at its middle)"},
          {"--area", "X0,Y0,X1,Y1", "the machine coordinates shown (default: the travel)"},
          {"--plain", "", "the view alone, without the travel, area and axes drawn", Given::flag}},
         R"(The photo projected through the camera's model and the bed plane, at the stock's top,
onto the machine's coordinates as a job compensated through the result means them: a point
drawn at X,Y in the view is where such a job aimed at X,Y lands. North is up; the world file
(ESRI, six lines) gives the pixel size and the centre of the top-left pixel in machine mm.
The machine's travel (blue), the area the result was measured over (green) and the machine's
X and Y axes (red) are drawn, with a line giving the scale, the height and the accuracy: two
standard deviations of a point, from the camera's and the plane's reprojection and what the
planar model leaves. Where the camera does not see, the view is black. Refused: a photo of
another size than the camera's, an area beyond the travel, a view over 40 megapixels, a
result from before calbox recorded its frame.)",
         view_bed},
        {"view stock",
         "the sheet on the bed: its corners and turn in the machine's coordinates",
         {{"--camera", "camera.yaml", "the camera's calibration", Given::required},
          {"--plane", "plane.yaml", "the bed plane", Given::required},
          {"--result", "result.json", "the planar result in force (calbox solve planar)",
           Given::required},
          {"IMAGE", "", "a photo of the sheet from the same camera on its mount", Given::word},
          {"--stock-thickness", "MM", "the sheet's top above the bed", Given::required},
          {"-o", "stock.json", "the sheet's corners, written", Given::required},
          {"--overlay", "PNG", "the bed view with the sheet's outline drawn, written"},
          {"--mm-per-px", "MM", "the overlay's scale (default: the photo's own at its middle)"}},
         R"(Finds a rectangular sheet lying on the bed (light or dark against it, turned any way) and
gives its four corners in the machine's coordinates, as a job compensated through the result
means them (see calbox view bed), each with its standard uncertainty, and the front edge's
turn against +X. The outline is found on a coarse view of the travel; each edge is then
measured in the photo every 2 mm across it, clear of the corners, mapped onto the machine at
the sheet's top and fitted with a line; a point off its line (a chip, a clamp) is set aside,
and so is a point where the sensor clipped the edge (the lamp's glare). The corners are named
front-left, front-right, back-right, back-left (the front is the machine's -Y side).
calbox compensate --work-zero camera --stock stock.json places a job at one of them.
Refused: a sheet that runs on beyond what the camera sees, an edge that shows over under half
its length, a result from before calbox recorded its frame.)",
         view_stock},
        {"view marks",
         "a printed drawing's place from its registration marks (print and cut)",
         {{"--camera", "camera.yaml", "the camera's calibration", Given::required},
          {"--plane", "plane.yaml", "the bed plane", Given::required},
          {"--result", "result.json", "the planar result in force (calbox solve planar)",
           Given::required},
          {"IMAGE", "", "a photo of the printed sheet from the same camera on its mount",
           Given::word},
          {"--marks", "X,Y;X,Y;X,Y[;X,Y]",
           "the marks' places in the drawing (mm), three or four; markers as ID:X,Y",
           Given::required},
          {"--mark-kind", "circles|crosses|markers",
           "filled circles (the default), crosses (two crossed bars) or ArUco/AprilTag markers, "
           "each told by its id"},
          {"--dict", "NAME", "the markers' dictionary (default DICT_4X4_50)"},
          {"--mark-diameter", "MM",
           "the circles' diameter, the crosses' span or the markers' side (default 5)"},
          {"--mark-line", "MM", "the crosses' bar width (default 0.5)"},
          {"--stock-thickness", "MM", "the printed sheet's top above the bed (default 0)"},
          {"--max-residual", "MM", "the farthest a mark may lie from the fit (default 0.1)"},
          {"-o", "marks.json", "the drawing's place, written", Given::required}},
         R"(Finds the drawing's registration marks (filled dark circles, --mark-diameter across; dark
crosses with --mark-kind crosses, --mark-diameter tip to tip with bars --mark-line wide; or
ArUco/AprilTag markers with --mark-kind markers, each mark given as ID:X,Y of its centre) in
the photo, matches them to their places in the drawing whatever way the sheet lies, and fits
where the drawing lies on the machine (as a job compensated through the result means it):
turned and shifted, and with four marks its scale too (a printer's stretch). Each mark's
residual from the fit is printed. calbox compensate --register marks.json then places a job
written in the drawing's frame there. Refused: marks not all found, marks laid
symmetrically (the drawing would fit two ways: move one), a mark farther from the fit than
--max-residual (a misprint, a smudge, a sheet not flat), a scale over 3 % off.)",
         view_marks},
    };
}

}  // namespace calbox::cli
