// calbox detect markers|chessboard|circles: what the box sees.
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/geometry/calibration.hpp"
#include "core/vision/markers.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/cli_images.hpp"

namespace calbox::cli {
namespace {

constexpr const char* kSchema = "calbox.detections/1";

nlohmann::json point_json(const geometry::Point2& p) {
    return nlohmann::json::array({p.x, p.y});
}

cv::Mat colour_copy(const cv::Mat& gray) {
    cv::Mat colour;
    cv::cvtColor(gray, colour, cv::COLOR_GRAY2BGR);
    return colour;
}

void emit(const Args& args, const nlohmann::json& j) {
    if (const auto out = args.get("-o")) {
        write_output_file(*out, j.dump(1) + "\n");
    } else {
        std::cout << j.dump(1) << "\n";
    }
}

int markers(const Args& args, const std::string& image_path) {
    const cv::Mat gray = load_gray_image(image_path);
    vision::MarkerOptions options;
    options.dictionary = args.get("--dict").value_or("DICT_4X4_50");
    options.refine_edges = !args.flag("--no-refine");
    std::optional<geometry::CameraModel> camera;
    if (const auto path = args.get("--camera")) {
        camera = geometry::camera_from_yaml(read_input_file(*path, "camera file"));
        if (const auto size = geometry::photo_size_mismatch(*camera, gray.cols, gray.rows);
            !size.empty())
            throw std::runtime_error("the image is " + size);
        options.camera = &*camera;
    }
    const auto found = vision::detect_markers(view_of(gray), options);
    if (found.empty())
        throw std::runtime_error("no " + options.dictionary + " markers found in " + image_path);
    nlohmann::json list = nlohmann::json::array();
    for (const auto& m : found) {
        nlohmann::json corners = nlohmann::json::array();
        for (const auto& c : m.corners) corners.push_back(point_json(c));
        nlohmann::json marker{{"id", m.id}, {"corners", corners}, {"refined", m.refined}};
        if (!m.refined) marker["unrefined_because"] = m.unrefined_because;
        list.push_back(std::move(marker));
    }
    const auto unrefined =
        std::count_if(found.begin(), found.end(), [](const auto& m) { return !m.refined; });
    emit(args, {{"schema", kSchema},
                {"image", image_path},
                {"image_width", gray.cols},
                {"image_height", gray.rows},
                {"dictionary", options.dictionary},
                {"refine_edges", options.refine_edges},
                {"unrefined", unrefined},
                {"markers", list}});
    if (const auto overlay = args.get("--overlay")) {
        cv::Mat picture = colour_copy(gray);
        const int thickness = std::max(1, gray.cols / 1000);
        for (const auto& m : found) {
            std::vector<cv::Point> outline;
            for (const auto& c : m.corners) outline.emplace_back(cvRound(c.x), cvRound(c.y));
            cv::polylines(picture, outline, true, cv::Scalar(0, 200, 0), thickness);
            cv::drawMarker(picture, outline[0], cv::Scalar(0, 0, 255), cv::MARKER_CROSS,
                           6 * thickness, thickness);
            cv::putText(picture, std::to_string(m.id), outline[0] + cv::Point(4, -4) * thickness,
                        cv::FONT_HERSHEY_SIMPLEX, std::max(0.6, gray.cols / 1600.0),
                        cv::Scalar(255, 80, 0), thickness);
        }
        write_png(*overlay, picture);
    }
    if (args.get("-o")) {
        std::printf("found %zu markers", found.size());
        if (options.refine_edges && unrefined > 0)
            std::printf(", %ld kept as the detector found them (refined: false)",
                        static_cast<long>(unrefined));
        std::printf("\n");
    }
    return 0;
}

int board(const Args& args, const std::string& image_path, bool circles) {
    const auto pattern = geometry::parse_pattern_spec(args.require("--pattern"));
    if (circles != pattern.is_circles() ||
        (!circles && pattern.kind != geometry::PatternSpec::Kind::chessboard)) {
        throw UsageError(
            std::string("detect ") +
            (circles ? "circles needs a circles: or acircles:" : "chessboard needs a chessboard:") +
            " pattern");
    }
    const cv::Mat gray = load_gray_image(image_path);
    const auto found = geometry::find_board(pattern, view_of(gray));
    if (!found)
        throw std::runtime_error("no " + args.require("--pattern") + " found in " + image_path);
    nlohmann::json points = nlohmann::json::array();
    for (const auto& p : found->image_points) points.push_back(point_json(p));
    emit(args, {{"schema", kSchema},
                {"image", image_path},
                {"image_width", gray.cols},
                {"image_height", gray.rows},
                {"pattern", args.require("--pattern")},
                {circles ? "centres" : "corners", points}});
    if (const auto overlay = args.get("--overlay")) {
        cv::Mat picture = colour_copy(gray);
        std::vector<cv::Point2f> corners;
        for (const auto& p : found->image_points)
            corners.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
        cv::drawChessboardCorners(picture, cv::Size(pattern.columns, pattern.rows), corners, true);
        write_png(*overlay, picture);
    }
    return 0;
}

int detect_markers(const Args& args) {
    return markers(args, args.positional().front());
}

int detect_chessboard(const Args& args) {
    return board(args, args.positional().front(), false);
}

int detect_circles(const Args& args) {
    return board(args, args.positional().front(), true);
}

}  // namespace

std::vector<Command> detect_commands() {
    const Option image{"IMAGE", "", "the image", Given::word};
    const Option out{"-o", "detections.json",
                     "what was found, written (without it: to standard output)"};
    const Option overlay{"--overlay", "PNG", "the image with what was found drawn on it"};
    const char* found_details =
        R"(Writes the pixel positions of what was found as JSON. Pixels use OpenCV's convention
(pixel centres at integer coordinates). Finding nothing is an error.)";
    return {
        {"detect markers",
         "ArUco or AprilTag markers in an image",
         {image,
          {"--dict", "NAME",
           "the dictionary (default DICT_4X4_50): OpenCV's names, DICT_4X4_50 ... "
           "DICT_APRILTAG_36h11, or tag36h11, tag25h9, tagStandard41h12 (libapriltag)"},
          {"--camera", "camera.yaml", "refine the corners as straight lines after undistortion"},
          {"--no-refine", "", "keep the corners as the detector found them", Given::flag},
          out,
          overlay},
         std::string(found_details) +
             R"( Marker corners are in OpenCV's order, refined by fitting
each outer edge over its length (with --camera, as straight lines after undistortion).)",
         detect_markers},
        {"detect chessboard",
         "a chessboard's inner corners in an image",
         {image,
          {"--pattern", "chessboard:COLSxROWS@MM", "the board", Given::required},
          out,
          overlay},
         found_details,
         detect_chessboard},
        {"detect circles",
         "a dot grid's centres in an image",
         {image,
          {"--pattern", "circles:COLSxROWS@MM|acircles:COLSxROWS@MM", "the grid", Given::required},
          out,
          overlay},
         found_details,
         detect_circles},
    };
}

}  // namespace calbox::cli
