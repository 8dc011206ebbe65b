// calbox view bed: a photo of the bed seen in the machine's coordinates.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "core/modes/bed_view.hpp"
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

int view_bed(const Args& args) {
    const std::string out = args.require("-o");
    if (out.size() < 5 || out.substr(out.size() - 4) != ".png")
        throw UsageError("-o must name a .png (its world file is written beside it as .pgw)",
                         "calbox view bed");
    const std::string world = out.substr(0, out.size() - 4) + ".pgw";
    modes::BedViewRequest request;
    request.surface_height_mm = args.number("--stock-thickness", 0);
    request.mm_per_px = args.number("--mm-per-px", 0);
    if (args.get("--mm-per-px") && !(request.mm_per_px > 0))
        throw UsageError("--mm-per-px must be above 0", "calbox view bed");
    if (const auto area = args.get("--area")) read_area(*area, request);
    const auto camera =
        geometry::camera_from_yaml(read_input_file(args.require("--camera"), "camera file"));
    const auto plane =
        geometry::plane_from_yaml(read_input_file(args.require("--plane"), "plane file"));
    const std::string result_name = args.require("--result");
    const auto solution =
        modes::planar_result_from_json(read_input_file(result_name, "result"), result_name);
    const std::string photo_name = args.positional()[0];
    const cv::Mat photo = load_gray_image(photo_name);
    modes::BedView view;
    try {
        view =
            modes::render_bed_view(camera, plane, view_of(photo), solution, request, result_name);
    } catch (const modes::BedViewError& e) {
        throw std::runtime_error(photo_name + ": " + e.what());
    }
    cv::Mat picture;
    if (args.flag("--plain")) {
        picture = cv::Mat(view.pixels.height_px, view.pixels.width_px, CV_8UC1,
                          view.pixels.pixels.data());
    } else {
        auto colour = modes::bed_view_with_overlay(view, solution);
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
    };
}

}  // namespace calbox::cli
