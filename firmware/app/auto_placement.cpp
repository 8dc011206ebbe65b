#include "firmware/app/auto_placement.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "board/sim/gcode_runner.hpp"
#include "board/sim/router_twin.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/scenes.hpp"
#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/modes/compensate_job.hpp"
#include "core/modes/planar.hpp"
#include "core/modes/registration.hpp"
#include "core/modes/stock.hpp"
#include "core/number_text.hpp"

namespace calbox::firmware {
namespace {

std::string read_whole(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("[placement] job: cannot read " + path.string());
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

// The judge's own reading of a drilling job (the example's and its placed copy): each plunge's
// X Y, the last rapid's before a feed down in Z.
std::vector<geometry::Point2> plunges(const std::string& job) {
    std::vector<geometry::Point2> found;
    geometry::Point2 at;
    std::istringstream lines(job);
    for (std::string line; std::getline(lines, line);) {
        double x = 0, y = 0;
        if (std::sscanf(line.c_str(), "G0 X%lf Y%lf", &x, &y) == 2) at = {x, y};
        if (line.rfind("G1 Z-", 0) == 0) found.push_back(at);
    }
    return found;
}

// What the box has: its set-up's camera and plane, the correction in force.
struct BoxSide {
    geometry::CameraModel camera;
    geometry::BedPlane plane;
    modes::PlanarSolution solution;
};

BoxSide box_side(hal::Storage& data, const std::string& kept_result_text) {
    const auto camera_yaml = data.read_file("camera.yaml");
    const auto plane_yaml = data.read_file("plane.yaml");
    if (!camera_yaml || !plane_yaml)
        throw std::runtime_error("placement: the box has no camera.yaml or plane.yaml");
    return {geometry::camera_from_yaml(*camera_yaml), geometry::plane_from_yaml(*plane_yaml),
            modes::planar_result_from_json(kept_result_text, "the correction in force")};
}

// Print and cut: the box finds the card's marks in its photo and places the cut by them
// (what `calbox view marks` and `calbox compensate --register` do); the judge runs the placed
// cut on the twin's machine and measures each point it cut from the printed line.
void judge_print_and_cut(const sim::TwinBench& bench, hal::Storage& data,
                         const std::string& kept_result_text) {
    const auto& scenario = bench.scenario();
    const auto& placement = *scenario.placement;
    const auto& card = *placement.card;
    const auto box = box_side(data, kept_result_text);
    const auto job_path = std::filesystem::path(scenario.path).parent_path() / placement.job_path;
    const std::string job = read_whole(job_path);
    const auto photo = bench.photograph_card(card, placement.thickness_mm);
    const vision::GrayView view{photo.pixels.data(), photo.width_px, photo.height_px,
                                photo.width_px};
    modes::RegistrationRequest marks;
    for (const auto& m : card.marks_mm) marks.marks_drawing_mm.push_back({m.x, m.y});
    marks.mark_diameter_mm = card.mark_diameter_mm;
    marks.surface_height_mm = placement.thickness_mm;
    const auto registration = modes::register_marks(box.camera, box.plane, view, box.solution,
                                                    marks, "the correction in force");
    modes::JobRequest request;
    request.result_text = kept_result_text;
    request.result_name = "the correction in force";
    request.job_text = job;
    request.job_name = job_path.filename().string();
    request.registration_text =
        modes::registration_to_json(registration, box.solution.machine_fingerprint);
    request.registration_name = "placement-marks.json";
    request.date = "the sim board";
    const auto placed = modes::compensate_job(request);
    data.replace_file("placement-marks.json", *request.registration_text);
    data.replace_file("placement-job-compensated.nc", placed.text);
    std::printf("placement: %s\n", placed.frame_line.c_str());

    // The judge's part, in the twin's truth: the placed cut run on the twin's laser, each point
    // it cut against the line printed on the card. The controller's zero is set where the marks
    // put the drawing's (a laser's grbl keeps its work frame at the machine's: G92 there).
    auto machine = sim::make_machine_twin(scenario);
    sim::GcodeRunner runner(*machine, sim::tool_settings_of(scenario));
    if (!machine->homed()) runner.run_line("G28");
    runner.run_line("G0 X" + number_text("%.6f", registration.origin_mm.x) + " Y" +
                    number_text("%.6f", registration.origin_mm.y));
    runner.run_line("G92 X0 Y0");
    std::istringstream run(placed.text);
    runner.run(run);
    std::vector<sim::Vec2> printed;
    for (const auto& p : card.line_mm) printed.push_back(card.on_bed(p));
    double worst = 0, sum = 0;
    std::size_t points = 0;
    for (const auto& s : runner.result().strokes)
        for (const sim::Vec3& p : {s.a_mm, s.b_mm}) {
            const double d = sim::distance_to_polyline({p.x, p.y}, printed);
            worst = std::max(worst, d);
            sum += d;
            ++points;
        }
    if (points == 0) throw std::runtime_error("placement: the placed cut cut nothing on the twin");
    const double mean = sum / static_cast<double>(points);
    std::printf(
        "placement: %zu marks, the drawing turned %s deg, scale %s, worst mark %s mm; the cut "
        "%s mm mean, %s mm worst from the printed line over %zu points (goal %s mm)\n",
        registration.marks.size(), number_text("%.3f", registration.rotation_deg).c_str(),
        number_text("%.5f", registration.scale).c_str(),
        number_text("%.4f", registration.worst_residual_mm).c_str(),
        number_text("%.4f", mean).c_str(), number_text("%.4f", worst).c_str(), points,
        number_text("%.3f", placement.goal_mm).c_str());
    if (worst > placement.goal_mm)
        throw std::runtime_error("the placement goal is not met: the cut " +
                                 number_text("%.4f", worst) + " mm from the printed line (goal " +
                                 number_text("%.3f", placement.goal_mm) + " mm)");
}

// A sheet's corner: the box finds the sheet and places the drilling job at its corner; the judge
// drills each hole on the twin's router against where the job meant it on the sheet.
void judge_sheet_placement(const sim::TwinBench& bench, hal::Storage& data,
                           const std::string& kept_result_text) {
    const auto& scenario = bench.scenario();
    const auto& placement = *scenario.placement;
    // The box's part: what it has (its set-up and correction) and what the camera sees.
    const auto [camera, plane, solution] = box_side(data, kept_result_text);
    const auto photo = bench.photograph_sheet(placement.sheet, placement.thickness_mm);
    const vision::GrayView view{photo.pixels.data(), photo.width_px, photo.height_px,
                                photo.width_px};
    const auto stock =
        modes::find_stock(camera, plane, view, solution, placement.thickness_mm, "the bed photo");
    const auto job_path = std::filesystem::path(scenario.path).parent_path() / placement.job_path;
    const std::string job = read_whole(job_path);
    modes::JobRequest request;
    request.result_text = kept_result_text;
    request.result_name = "the correction in force";
    request.job_text = job;
    request.job_name = job_path.filename().string();
    request.work_zero = "camera";
    request.stock_text = modes::stock_to_json(stock, solution.machine_fingerprint);
    request.stock_name = "placement-stock.json";
    request.stock_corner = placement.corner;
    request.date = "the sim board";
    const auto placed = modes::compensate_job(request);
    data.replace_file("placement-stock.json", *request.stock_text);
    data.replace_file("placement-job-compensated.nc", placed.text);
    std::printf("placement: %s\n", placed.frame_line.c_str());

    // The judge's part, in the twin's truth: the controller's G54 set at the corner the box
    // found, each hole drilled where the router really goes for it, against where the job meant
    // it on the sheet (the chosen corner, the job turned with the sheet's front edge).
    const auto& chosen = modes::stock_corner(stock, placement.corner);
    std::size_t k = 0;
    while (k < 4 && stock.corners[k].name != chosen.name) ++k;
    const auto truth_corners = sim::SheetScene(placement.sheet, 1).corners();
    const sim::Vec2 corner = truth_corners[k];
    const double turn = placement.sheet.angle_deg * std::numbers::pi / 180;
    const auto& truth = scenario.router_truth;
    const auto written = plunges(placed.text);
    const auto meant = plunges(job);
    if (written.size() != meant.size() || meant.empty())
        throw std::runtime_error("placement: the placed job drills " +
                                 std::to_string(written.size()) + " holes, the job " +
                                 std::to_string(meant.size()));
    double worst = 0, sum = 0;
    for (std::size_t i = 0; i < written.size(); ++i) {
        const sim::Vec3 command{written[i].x + chosen.machine_mm.x - truth.g54_x_mm,
                                written[i].y + chosen.machine_mm.y - truth.g54_y_mm,
                                -scenario.machine.cut_depth_mm};
        const sim::Vec3 tool = sim::router_tool_position_mm(truth, command, {true, true});
        const sim::Vec2 on_sheet{
            corner.x + meant[i].x * std::cos(turn) - meant[i].y * std::sin(turn),
            corner.y + meant[i].x * std::sin(turn) + meant[i].y * std::cos(turn)};
        const double off = std::hypot(tool.x - on_sheet.x, tool.y - on_sheet.y);
        worst = std::max(worst, off);
        sum += off;
    }
    const double mean = sum / static_cast<double>(written.size());
    // The turn is the front edge's against the machine's axes, which lie turned on the bed.
    std::printf(
        "placement: the sheet's %s corner, turned %s deg in the machine's axes (%s on the "
        "bed's); %zu holes %s mm mean, %s mm worst from where the job meant them on the "
        "sheet (goal %s mm)\n",
        chosen.name.c_str(), number_text("%.3f", stock.rotation_deg).c_str(),
        number_text("%.3f", placement.sheet.angle_deg).c_str(), written.size(),
        number_text("%.4f", mean).c_str(), number_text("%.4f", worst).c_str(),
        number_text("%.3f", placement.goal_mm).c_str());
    if (worst > placement.goal_mm)
        throw std::runtime_error("the placement goal is not met: a hole " +
                                 number_text("%.4f", worst) + " mm from where the job meant it " +
                                 "on the sheet (goal " + number_text("%.3f", placement.goal_mm) +
                                 " mm)");
}

}  // namespace

void judge_placement(const sim::TwinBench& bench, hal::Storage& data,
                     const std::string& kept_result_text) {
    if (bench.scenario().placement->card)
        judge_print_and_cut(bench, data, kept_result_text);
    else
        judge_sheet_placement(bench, data, kept_result_text);
}

}  // namespace calbox::firmware
