// calbox camera calibrate|plane
#include <cstdio>
#include <iostream>

#include "core/geometry/calibration.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/cli_images.hpp"

namespace calbox::cli {
namespace {

constexpr const char* kCameraHelp = R"(usage:
  calbox camera calibrate --pattern SPEC [--model pinhole|fisheye] IMAGES... -o camera.yaml
      Intrinsic calibration from views of a board: SPEC is chessboard:COLSxROWS@MM (inner
      corners), charuco:COLSxROWS@SQUARE_MM/MARKER_MM:DICT (squares), circles:COLSxROWS@MM or
      acircles:COLSxROWS@MM. Views where the board is not found are skipped and listed; a pinhole
      needs at least 3 usable views and 60 corners, a fisheye 4 and 80. A view reprojecting
      far beyond the others (5 times the better views, and over 1 px) is re-solved through the
      others' camera or dropped, with a line saying which and why. Nothing is written when the
      views left are too few or the RMS exceeds 1 px (pinhole) or 1.5 px (fisheye). Prints each
      view's reprojection RMS and which detector found it.
  calbox camera plane --camera camera.yaml --pattern SPEC [--thickness MM] IMAGE -o plane.yaml
      The bed plane from one image of a board lying on the bed, its surface --thickness mm
      (default 0) above the bed. The bed frame is right-handed with z up, its origin under the
      board's first inner corner, x along the board's columns.
)";

geometry::LensModel model_from(const Args& args) {
    const std::string model = args.get("--model").value_or("pinhole");
    if (model == "pinhole") return geometry::LensModel::pinhole;
    if (model == "fisheye") return geometry::LensModel::fisheye;
    throw UsageError("--model must be pinhole or fisheye, not '" + model + "'");
}

int calibrate(const std::vector<std::string>& words) {
    const Args args(words, {"--pattern", "--model", "-o"}, {});
    const auto pattern = geometry::parse_pattern_spec(args.require("--pattern"));
    const auto model = model_from(args);
    const std::string out = args.require("-o");
    if (args.positional().empty()) throw UsageError("camera calibrate needs images");
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

int plane(const std::vector<std::string>& words) {
    const Args args(words, {"--camera", "--pattern", "--thickness", "-o"}, {});
    const auto camera =
        geometry::camera_from_yaml(read_input_file(args.require("--camera"), "camera file"));
    const auto pattern = geometry::parse_pattern_spec(args.require("--pattern"));
    const double thickness = args.number("--thickness", 0);
    const std::string out = args.require("-o");
    if (args.positional().size() != 1) throw UsageError("camera plane takes one image");
    const cv::Mat image = load_gray_image(args.positional()[0]);
    const auto plane = geometry::estimate_bed_plane(camera, pattern, view_of(image), thickness);
    std::printf("bed plane: board reprojection RMS %.4f px, camera %.2f mm from the bed origin\n",
                plane.rms_px,
                std::hypot(plane.bed_to_camera.tvec_mm[0], plane.bed_to_camera.tvec_mm[1],
                           plane.bed_to_camera.tvec_mm[2]));
    write_output_file(out, geometry::plane_to_yaml(plane));
    return 0;
}

}  // namespace

int run_camera(const std::vector<std::string>& words) {
    return dispatch(words, kCameraHelp, "camera", {{"calibrate", calibrate}, {"plane", plane}});
}

}  // namespace calbox::cli
