// calbox camera calibrate|plane
#include <cstdio>
#include <iostream>

#include "core/geometry/calibration.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/cli_images.hpp"

namespace calbox::cli {
namespace {

geometry::LensModel model_from(const Args& args) {
    const std::string model = args.get("--model").value_or("pinhole");
    if (model == "pinhole") return geometry::LensModel::pinhole;
    if (model == "fisheye") return geometry::LensModel::fisheye;
    throw UsageError("--model must be pinhole or fisheye, not '" + model + "'");
}

int calibrate(const Args& args) {
    const auto pattern = geometry::parse_pattern_spec(args.require("--pattern"));
    const auto model = model_from(args);
    const std::string out = args.require("-o");
    std::vector<cv::Mat> images;
    std::vector<geometry::NamedImage> views;
    for (const auto& path : args.positional()) images.push_back(load_gray_image(path));
    for (std::size_t i = 0; i < images.size(); ++i)
        views.push_back({args.positional()[i], view_of(images[i])});
    const auto result = geometry::calibrate_camera(pattern, model, views);
    std::vector<double> per_view;
    for (const auto& v : result.views) {
        std::printf("view %s: %d points (%s), reprojection RMS %.4f px%s%s\n", v.name.c_str(),
                    v.points, v.detector.c_str(), v.rms_px, v.note.empty() ? "" : "; ",
                    v.note.c_str());
        per_view.push_back(v.rms_px);
    }
    for (const auto& s : result.skipped) std::printf("skipped %s: board not found\n", s.c_str());
    for (const auto& d : result.dropped)
        std::printf("dropped %s: %s\n", d.name.c_str(), d.why.c_str());
    const auto& c = result.camera;
    std::printf("%s camera %dx%d: fx %.3f fy %.3f cx %.3f cy %.3f, RMS %.4f px over %zu views\n",
                geometry::lens_model_name(model), c.image_width, c.image_height, c.fx(), c.fy(),
                c.cx(), c.cy(), c.rms_px, result.views.size());
    write_output_file(out, geometry::camera_to_yaml(c, per_view));
    return 0;
}

int plane(const Args& args) {
    const auto camera =
        geometry::camera_from_yaml(read_input_file(args.require("--camera"), "camera file"));
    const auto pattern = geometry::parse_pattern_spec(args.require("--pattern"));
    const double thickness = args.number("--thickness", 0);
    const std::string out = args.require("-o");
    const cv::Mat image = load_gray_image(args.positional()[0]);
    const auto plane = geometry::estimate_bed_plane(camera, pattern, view_of(image), thickness);
    std::printf("bed plane: board reprojection RMS %.4f px, camera %.2f mm from the bed origin%s\n",
                plane.rms_px,
                std::hypot(plane.bed_to_camera.tvec_mm[0], plane.bed_to_camera.tvec_mm[1],
                           plane.bed_to_camera.tvec_mm[2]),
                geometry::set_aside_text(plane).c_str());
    write_output_file(out, geometry::plane_to_yaml(plane));
    return 0;
}

}  // namespace

std::vector<Command> camera_commands() {
    const Option pattern{"--pattern", "SPEC",
                         "the board: chessboard:COLSxROWS@MM (inner corners), "
                         "charuco:COLSxROWS@SQUARE_MM/MARKER_MM:DICT (squares), "
                         "circles:COLSxROWS@MM or acircles:COLSxROWS@MM",
                         Given::required};
    return {
        {"camera calibrate",
         "the camera's intrinsics from views of a board",
         {pattern,
          {"--model", "pinhole|fisheye", "the lens model (default pinhole)"},
          {"IMAGES", "", "views of the board", Given::words},
          {"-o", "camera.yaml", "the calibration, written", Given::required}},
         R"(Intrinsic calibration from views of a board. Views where the board is not found are
skipped and listed; a pinhole needs at least 3 usable views and 60 corners, a fisheye 4 and
80. A view reprojecting far beyond the others (5 times the better views, and over 1 px) is
re-solved through the others' camera or dropped, with a line saying which and why. Nothing is
written when the views left are too few or the RMS exceeds 1 px (pinhole) or 1.5 px
(fisheye). Prints each view's reprojection RMS and which detector found it.)",
         calibrate},
        {"camera plane",
         "the bed plane from one image of a board lying on the bed",
         {{"--camera", "camera.yaml", "the camera's calibration", Given::required},
          pattern,
          {"--thickness", "MM", "the board's surface above the bed (default 0)"},
          {"IMAGE", "", "the board on the bed", Given::word},
          {"-o", "plane.yaml", "the bed plane, written", Given::required}},
         R"(The bed plane from one image of a board lying on the bed, its surface --thickness mm
above the bed. The bed frame is right-handed with z up, its origin under the board's first
inner corner, x along the board's columns.)",
         plane},
    };
}

}  // namespace calbox::cli
