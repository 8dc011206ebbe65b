#include "firmware/cli/mode_verbs.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "core/geometry/camera_model.hpp"
#include "firmware/cli/cli_images.hpp"

namespace calbox::cli {

std::vector<ModeVerbs> mode_verbs() {
    return {delta_verbs(), galvo_verbs(), planar_verbs()};
}

std::string modes_line(std::size_t width) {
    std::string text = "modes:";
    std::size_t line_start = 0;
    const auto modes = mode_verbs();
    for (std::size_t m = 0; m < modes.size(); ++m) {
        const std::string entry =
            modes[m].name + " (" + modes[m].machines + ")" + (m + 1 < modes.size() ? "," : "");
        std::size_t from = 0;
        while (from < entry.size()) {  // word by word, so that a long entry wraps too
            const std::size_t space = entry.find(' ', from);
            const std::string word =
                entry.substr(from, space == std::string::npos ? std::string::npos : space - from);
            from = space == std::string::npos ? entry.size() : space + 1;
            if (text.size() - line_start + 1 + word.size() > width) {
                text += '\n';
                line_start = text.size();
            } else {
                text += ' ';
            }
            text += word;
        }
    }
    return text;
}

std::vector<Command> measure_commands() {
    std::vector<Command> commands;
    for (auto& verbs : mode_verbs()) commands.push_back(std::move(verbs.measure));
    return commands;
}

std::vector<Command> solve_commands() {
    std::vector<Command> commands;
    for (auto& verbs : mode_verbs()) commands.push_back(std::move(verbs.solve));
    return commands;
}

SetUp read_set_up(const Args& args) {
    const std::string machine_path = args.require("--machine");
    return {
        geometry::camera_from_yaml(read_input_file(args.require("--camera"), "camera file")),
        geometry::plane_from_yaml(read_input_file(args.require("--plane"), "plane file")),
        models::parse_machine_file(read_input_file(machine_path, "machine file"), machine_path)};
}

void draw_preview(const std::string& path, const jobs::PlacedJob& job,
                  const models::MachineFile& machine) {
    const double margin_mm = 2 + job.line_width_mm;
    const double width_mm = job.max_x - job.min_x + 2 * margin_mm,
                 height_mm = job.max_y - job.min_y + 2 * margin_mm;
    const double px_per_mm = 1200.0 / std::max(width_mm, height_mm);
    const int text_rows = 70;
    cv::Mat picture(static_cast<int>(height_mm * px_per_mm) + text_rows,
                    static_cast<int>(width_mm * px_per_mm), CV_8UC3, cv::Scalar(255, 255, 255));
    constexpr int kShift = 4;  // sub-pixel drawing
    const auto to_px = [&](geometry::Point2 p) {
        return cv::Point(static_cast<int>(std::lround((p.x - job.min_x + margin_mm) * px_per_mm *
                                                      (1 << kShift))),
                         static_cast<int>(std::lround((job.max_y + margin_mm - p.y) * px_per_mm *
                                                      (1 << kShift))));
    };
    const int line_px = std::max(1, static_cast<int>(std::lround(job.line_width_mm * px_per_mm)));
    for (const auto& move : job.toolpath.moves) {
        cv::Scalar colour(0, 0, 220);  // travel
        int thickness = 1;
        if (move.kind == jobs::MoveKind::perimeter) colour = cv::Scalar(200, 90, 0);
        if (move.kind == jobs::MoveKind::infill) colour = cv::Scalar(60, 170, 60);
        if (move.kind == jobs::MoveKind::trace) colour = cv::Scalar(160, 40, 160);
        if (move.kind != jobs::MoveKind::travel) thickness = line_px;
        cv::line(picture, to_px(move.from), to_px(move.to), colour, thickness, cv::LINE_AA, kShift);
    }
    char text[256];
    std::snprintf(text, sizeof text,
                  "path %.1f mm, travel %.1f mm (%.1f %%), about %.0f s at %.0f mm/s",
                  job.toolpath.working_length_mm(), job.toolpath.travel_length_mm(),
                  100 * job.toolpath.travel_length_mm() / job.toolpath.working_length_mm(),
                  job.estimated_time_s(machine), job.feed_mm_s);
    cv::putText(picture, text, cv::Point(10, picture.rows - 40), cv::FONT_HERSHEY_SIMPLEX, 0.6,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    std::snprintf(
        text, sizeof text,
        "%.2f x %.2f mm, line %.3f mm, spacing %.3f mm; blue perimeters, green infill, red travel",
        job.max_x - job.min_x, job.max_y - job.min_y, job.line_width_mm, job.spacing_mm);
    cv::putText(picture, text, cv::Point(10, picture.rows - 15), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    write_png(path, picture);
}

Option describe_option() {
    return {"--describe", "target.json", "every feature's commanded position, written"};
}
Option camera_option() {
    return {"--camera", "camera.yaml", "the camera's calibration", Given::required};
}
Option plane_option() {
    return {"--plane", "plane.yaml", "the bed plane", Given::required};
}
Option measurements_out_option() {
    return {"-o", "measurements.json", "the measurements, written", Given::required};
}
Option measurements_option() {
    return {"--measurements", "measurements.json", "the measurements (calbox measure)",
            Given::required};
}
Option result_out_option() {
    return {"-o", "result.json", "the result, written", Given::required};
}

}  // namespace calbox::cli
