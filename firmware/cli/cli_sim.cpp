// calbox sim print|photo: the digital twin on the command line.
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "board/sim/delta_judge.hpp"
#include "board/sim/print_json.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/scenes.hpp"
#include "board/sim/twin_kind.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/delta_records.hpp"
#include "core/modes/galvo.hpp"
#include "core/modes/planar.hpp"
#include "core/vision/image_codec.hpp"
#include "firmware/cli/cli_args.hpp"

namespace calbox::cli {
namespace {

std::array<double, 6> parse_numbers(const std::string& flag, const std::string& text,
                                    std::size_t count) {
    const auto refuse = [&] {
        std::string message = flag;
        message += " needs " + std::to_string(count) + " comma-separated numbers, not '";
        message += text;
        message += "'";
        throw UsageError(message);
    };
    std::array<double, 6> out{};
    std::stringstream in(text);
    std::string part;
    std::size_t n = 0;
    while (std::getline(in, part, ',')) {
        if (n >= count) refuse();
        std::size_t used = 0;
        double v = 0;
        try {
            v = std::stod(part, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (used != part.size() || part.empty() || !std::isfinite(v)) refuse();
        out[n++] = v;
    }
    if (n != count) refuse();
    return out;
}

sim::Scenario scenario_from(const Args& args) {
    return sim::load_scenario(args.require("--scenario"));
}

int sim_print(const Args& args) {
    const std::string job_path = args.positional()[0];
    const std::string out = args.require("-o");
    const auto scenario = scenario_from(args);
    auto machine = sim::make_machine_twin(scenario);
    sim::GcodeRunner runner(*machine, sim::tool_settings_of(scenario));
    std::istringstream job(read_input_file(job_path, "job"));
    try {
        runner.run(job);
    } catch (const sim::JobError& e) {
        throw std::runtime_error(job_path + ": " + e.what());
    }
    sim::PrintRecord record{scenario.path, job_path, scenario.machine.kind, runner.result()};
    write_output_file(out, sim::print_to_json(record));
    for (const auto& reply : record.result.replies) std::cout << reply << "\n";
    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
    double cxmin = 1e300, cxmax = -1e300, cymin = 1e300, cymax = -1e300;
    for (const auto& s : record.result.strokes) {
        for (const auto& p : {s.a_mm, s.b_mm}) {
            xmin = std::min(xmin, p.x), xmax = std::max(xmax, p.x);
            ymin = std::min(ymin, p.y), ymax = std::max(ymax, p.y);
        }
        for (const auto& p : {s.commanded_a_mm, s.commanded_b_mm}) {
            cxmin = std::min(cxmin, p.x), cxmax = std::max(cxmax, p.x);
            cymin = std::min(cymin, p.y), cymax = std::max(cymax, p.y);
        }
    }
    std::cout << "printed " << record.result.strokes.size() << " strokes from "
              << record.result.lines_run << " lines";
    if (!record.result.strokes.empty()) {
        char summary[256];
        std::snprintf(summary, sizeof summary,
                      "; nozzle path extent commanded %.4f x %.4f mm, actual %.4f x %.4f mm",
                      cxmax - cxmin, cymax - cymin, xmax - xmin, ymax - ymin);
        std::cout << summary;
    }
    std::cout << "\n";
    return 0;
}

nlohmann::json pose_json(const sim::Pose& pose) {
    const sim::Vec3 r = sim::vector_from_rotation(pose.rotation);
    return {{"rvec", {r.x, r.y, r.z}},
            {"tvec_mm", {pose.translation_mm.x, pose.translation_mm.y, pose.translation_mm.z}}};
}

nlohmann::json camera_json(const sim::CameraIntrinsics& c) {
    return {{"model", c.model == sim::LensModel::fisheye ? "fisheye" : "pinhole"},
            {"image_width", c.width_px},
            {"image_height", c.height_px},
            {"camera_matrix", {{c.fx, 0, c.cx}, {0, c.fy, c.cy}, {0, 0, 1}}},
            {"distortion_coefficients", c.distortion}};
}

nlohmann::json pixel_json(const sim::CameraIntrinsics& c, const sim::Pose& pose,
                          const sim::Vec3& p) {
    const sim::Vec3 q = pose.apply(p);
    if (q.z <= 0) return nullptr;
    const sim::Vec2 px = sim::project_point(c, pose, p);
    return {px.x, px.y};
}

// A sheet of stock lying on the bed (--sheet X,Y,WIDTH,DEPTH,ANGLE), its corners in the truth.
sim::GrayImage sheet_photo(const Args& args, const sim::Scenario& scenario,
                           const sim::Pose& bed_to_camera, nlohmann::json& truth) {
    const auto& camera = *scenario.camera;
    if (args.get("--pose") || args.get("--on-bed"))
        throw UsageError("--pose and --on-bed go with --board");
    const auto v = parse_numbers("--sheet", *args.get("--sheet"), 5);
    const double thickness = args.number("--thickness", 0);
    if (thickness < 0 || thickness > 50) throw UsageError("--thickness must be 0..50 mm");
    if (!(v[2] > 0 && v[3] > 0)) throw UsageError("--sheet needs a width and a depth above 0");
    sim::StockSheet sheet;
    sheet.corner_mm = {v[0], v[1]};
    sheet.width_mm = v[2], sheet.depth_mm = v[3], sheet.angle_deg = v[4];
    // A sheet that stands out against the scenario's bed: dark on a light bed, light on a
    // dark one.
    sheet.bed_albedo = scenario.bed_albedo;
    sheet.sheet_albedo = scenario.bed_albedo > 0.5 ? 0.15 : 0.8;
    const sim::SheetScene scene(sheet, scenario.photo.supersample);
    sim::Pose lifted;
    lifted.translation_mm = {0, 0, thickness};
    sim::GrayImage image =
        sim::render_photo(camera.intrinsics, sim::compose(bed_to_camera, lifted), scene,
                          sim::photo_settings_of(scenario, sim::InView::bed));
    nlohmann::json corners = nlohmann::json::array();
    for (const auto& c : scene.corners()) corners.push_back({c.x, c.y, thickness});
    truth["sheet_corners_mm"] = corners;
    return image;
}

// A print as its record laid it (--print), its strokes in the truth.
sim::GrayImage print_photo(const Args& args, const sim::Scenario& scenario,
                           const sim::Pose& bed_to_camera, nlohmann::json& truth) {
    const auto& camera = *scenario.camera;
    if (args.get("--pose") || args.get("--on-bed") || args.get("--thickness")) {
        throw UsageError("--pose, --on-bed and --thickness go with --board");
    }
    const auto record = sim::print_from_json(read_input_file(*args.get("--print"), "print record"));
    std::vector<sim::StrokeSegment> strokes;
    nlohmann::json stroke_truth = nlohmann::json::array();
    for (const auto& s : record.result.strokes) {
        strokes.push_back(sim::material_of(s));
        stroke_truth.push_back({{"a_mm", {s.a_mm.x, s.a_mm.y, s.a_mm.z}},
                                {"b_mm", {s.b_mm.x, s.b_mm.y, s.b_mm.z}},
                                {"a_px", pixel_json(camera.intrinsics, bed_to_camera, s.a_mm)},
                                {"b_px", pixel_json(camera.intrinsics, bed_to_camera, s.b_mm)},
                                {"width_mm", s.width_mm},
                                {"top_mm", {s.top_a_mm, s.top_b_mm}}});
    }
    // Photographed with the bed at another temperature than it was printed at, the print
    // has grown or shrunk with the bed; the truth keeps where the nozzle laid it.
    const double growth = sim::bed_growth_at_photo(scenario);
    strokes = sim::as_photographed(scenario, std::move(strokes));
    truth["bed_growth_at_photo"] = growth;
    const sim::StrokeScene scene(std::move(strokes), scenario.bed_albedo, scenario.material_albedo,
                                 scenario.photo.supersample, sim::stroke_footprint_mm(scenario));
    sim::GrayImage image = sim::render_photo(camera.intrinsics, bed_to_camera, scene,
                                             sim::photo_settings_of(scenario, sim::InView::bed));
    truth["strokes"] = stroke_truth;
    return image;
}

// The calibration board held at a pose or lying on the bed (--board), its features in the truth.
sim::GrayImage board_photo(const Args& args, const sim::Scenario& scenario,
                           const sim::Pose& bed_to_camera, nlohmann::json& truth) {
    const auto& camera = *scenario.camera;
    const auto spec = geometry::parse_pattern_spec(*args.get("--board"));
    sim::Pose board_to_camera;
    if (args.get("--pose").has_value() == args.get("--on-bed").has_value()) {
        throw UsageError("--board needs either --pose or --on-bed");
    }
    if (const auto pose = args.get("--pose")) {
        if (args.get("--thickness")) throw UsageError("--thickness goes with --on-bed");
        const auto v = parse_numbers("--pose", *pose, 6);
        board_to_camera.rotation =
            sim::rotation_from_vector(sim::Vec3{v[0], v[1], v[2]} * (sim::kPi / 180));
        board_to_camera.translation_mm = {v[3], v[4], v[5]};
    } else {
        const auto v = parse_numbers("--on-bed", *args.get("--on-bed"), 3);
        const double thickness = args.number("--thickness", 0);
        if (thickness < 0 || thickness > 50) throw UsageError("--thickness must be 0..50 mm");
        const sim::Pose board_to_bed = sim::board_lying_on_bed({v[0], v[1], thickness}, v[2]);
        board_to_camera = sim::compose(bed_to_camera, board_to_bed);
        truth["board_to_bed"] = pose_json(board_to_bed);
    }
    const sim::BoardScene scene(spec, scenario.photo.supersample);
    sim::GrayImage image = sim::render_photo(camera.intrinsics, board_to_camera, scene,
                                             sim::photo_settings_of(scenario, sim::InView::board));
    nlohmann::json features = nlohmann::json::array();
    for (const auto& f : scene.features()) {
        nlohmann::json j{{"id", f.id},
                         {"board_mm", {f.position_mm.x, f.position_mm.y, f.position_mm.z}},
                         {"pixel", pixel_json(camera.intrinsics, board_to_camera, f.position_mm)}};
        if (f.corner >= 0) j["corner"] = f.corner;
        features.push_back(j);
    }
    truth["board"] = *args.get("--board");
    truth["board_to_camera"] = pose_json(board_to_camera);
    truth["features"] = features;
    return image;
}

int sim_photo(const Args& args) {
    const std::string out = args.require("-o");
    const auto scenario = scenario_from(args);
    if (!scenario.camera)
        throw std::runtime_error(scenario.path + ": no [camera] section to take a photo with");
    const auto& camera = *scenario.camera;
    const sim::Pose bed_to_camera =
        sim::look_at_pose(camera.position_mm, camera.look_at_mm, camera.roll_deg);
    nlohmann::json truth{{"schema", "calbox.photo-truth/1"},
                         {"camera", camera_json(camera.intrinsics)},
                         {"bed_to_camera", pose_json(bed_to_camera)}};
    sim::GrayImage image;
    const bool has_print = args.get("--print").has_value();
    const bool has_board = args.get("--board").has_value();
    const bool has_sheet = args.get("--sheet").has_value();
    if (int{has_print} + int{has_board} + int{has_sheet} != 1)
        throw UsageError("sim photo needs one of --print, --board and --sheet");
    if (has_sheet)
        image = sheet_photo(args, scenario, bed_to_camera, truth);
    else if (has_print)
        image = print_photo(args, scenario, bed_to_camera, truth);
    else
        image = board_photo(args, scenario, bed_to_camera, truth);
    const auto png = vision::png_bytes(
        {image.pixels.data(), image.width_px, image.height_px, image.width_px, 1});
    write_output_file(out, std::string(png.begin(), png.end()));
    if (const auto t = args.get("--truth")) write_output_file(*t, truth.dump(1) + "\n");
    return 0;
}

int sim_measurements(const Args& args) {
    const auto scenario = scenario_from(args);
    auto machine = sim::make_machine_twin(scenario);
    const auto* delta = dynamic_cast<const sim::DeltaTwin*>(machine.get());
    if (delta == nullptr)
        throw std::runtime_error(scenario.path + ": measurements are made for delta scenarios");
    const int count = static_cast<int>(args.number("--features", 150));
    const double noise_mm = args.number("--noise", 0.01);
    if (count < 1 || count > 100000) throw UsageError("--features must be 1 to 100000");
    if (noise_mm < 0 || noise_mm > 5) throw UsageError("--noise must be 0 to 5 mm");
    const std::string out = args.require("-o");
    machine->home();
    std::mt19937_64 rng(static_cast<std::uint64_t>(args.number("--seed", 1)));
    std::normal_distribution<double> noise(0, noise_mm);
    const double radius = scenario.machine.bed_radius_mm * 0.92;
    nlohmann::json features = nlohmann::json::array();
    for (int k = 0; k < count; ++k) {
        const double r = radius * std::sqrt((k + 0.5) / count),
                     a = k * 2.399963229728653;  // a sunflower
        const sim::Vec3 commanded{r * std::cos(a), r * std::sin(a), 0.2};
        const sim::Vec3 actual = machine->actual_position_mm(commanded);
        std::string id = "f";  // appended: GCC 12's -O3 -Wrestrict misfires on "f" + string
        id += std::to_string(k);
        features.push_back({{"id", id},
                            {"commanded_mm", {commanded.x, commanded.y, commanded.z}},
                            {"measured_mm", {actual.x + noise(rng), actual.y + noise(rng)}},
                            {"sigma_mm", std::max(noise_mm, 1e-4)}});
    }
    nlohmann::json bars = nlohmann::json::array();
    for (const double angle : {210.0, 330.0, 90.0}) {
        const double t = sim::radians(angle);
        const sim::Vec3 a = machine->actual_position_mm({0, 0, 0.2}),
                        b = machine->actual_position_mm({60 * std::cos(t), 60 * std::sin(t), 0.2});
        bars.push_back({{"commanded_from_mm", 0.0},
                        {"commanded_to_mm", 60.0},
                        {"measured_mm", std::hypot(b.x - a.x, b.y - a.y)}});
    }
    // The firmware's belief as the twin holds it (its height zeroed at the centre, if asked).
    models::MachineFile believed = scenario.machine;
    believed.delta = sim::machine_settings(delta->firmware());
    const nlohmann::json j{{"schema", "calbox.measurements/1"},
                           {"machine_fingerprint", models::fingerprint(believed)},
                           {"source", "calbox sim measurements " + scenario.path},
                           {"features", features},
                           {"bars", bars}};
    write_output_file(out, j.dump(1) + "\n");
    if (const auto probe = args.get("--probe")) {
        std::string csv = "x,y,z\n";
        for (int k = 0; k < 37; ++k) {
            const int ring = k == 0 ? 0 : (k - 1) / 12 + 1;  // the centre, then three rings of 12
            const double r = radius * ring / 3.0, a = k * sim::kPi / 6;
            const sim::Vec3 at = machine->actual_position_mm({r * std::cos(a), r * std::sin(a), 0});
            char row[96];
            std::snprintf(row, sizeof row, "%.4f,%.4f,%.5f\n", r * std::cos(a), r * std::sin(a),
                          at.z + noise(rng) / 2);
            csv += row;
        }
        write_output_file(*probe, csv);
    }
    std::printf("%s: %d features, 3 bars, machine %s\n", out.c_str(), count,
                models::fingerprint(believed).c_str());
    return 0;
}

}  // namespace

// The twin judges a solve's result in its truth, each kind of machine its own way
// (board/sim/twin_kind).
int sim_verify(const Args& args) {
    const auto scenario = scenario_from(args);
    std::optional<sim::ResultFile> result;
    if (const auto path = args.get("--result"))
        result = sim::ResultFile{*path, read_input_file(*path, "result")};
    const auto verdict = sim::twin_kind_of(scenario.machine).verify(scenario, result);
    for (const auto& line : verdict.lines) std::printf("%s\n", line.c_str());
    if (const auto out = args.get("-o")) write_output_file(*out, verdict.json);
    return 0;
}

int sim_camera(const Args& args) {
    const auto scenario = scenario_from(args);
    if (!scenario.camera) throw std::runtime_error(scenario.path + ": no [camera] section");
    const auto model = sim::as_camera_model(scenario.camera->intrinsics);
    write_output_file(args.require("-o"), geometry::camera_to_yaml(model));
    return 0;
}

std::vector<Command> sim_commands() {
    const Option scenario{"--scenario", "FILE", "the twin's scenario", Given::required};
    return {
        {"sim print",
         "a job run on the twin's machine",
         {scenario,
          {"JOB.gcode", "", "the job", Given::word},
          {"-o", "print.json", "every stroke as it landed, written", Given::required}},
         R"(Runs the G-code job on the scenario's machine (true geometry, firmware belief) and writes
every stroke of material as it really landed. Prints the machine's replies (M503) and a
summary on standard output.)",
         sim_print},
        {"sim photo",
         "what the twin's camera sees of a print, a board or a sheet",
         {scenario,
          {"--print", "print.json", "a print (calbox sim print)"},
          {"--board", "SPEC",
           "a board: chessboard:COLSxROWS@SQUARE_MM (inner corners) or "
           "charuco:COLSxROWS@SQUARE_MM/MARKER_MM:DICT (squares)"},
          {"--pose", "RX,RY,RZ,TX,TY,TZ",
           "board -> camera: rotation vector in degrees (axis times angle), then mm"},
          {"--on-bed", "X,Y,ANGLE",
           "the board lying face up on the bed at X,Y mm, turned ANGLE degrees"},
          {"--sheet", "X,Y,W,D,ANGLE",
           "a sheet of stock on the bed: its corner at X,Y mm, W x D mm, turned ANGLE degrees"},
          {"--thickness", "MM",
           "the board's or the sheet's top above the bed, with --on-bed or --sheet (default 0)"},
          {"-o", "photo.png", "the photo, written", Given::required},
          {"--truth", "truth.json", "where every corner or stroke end truly is, written"}},
         R"(Renders what the scenario's camera sees of a print (--print), of a calibration board
(--board, placed by --pose or --on-bed), or of a sheet of stock on the bed (--sheet: dark on a light bed, light on a dark one).
--truth writes the true pixel position of every board corner and marker corner, or of every
stroke end, or the sheet's corners on the bed, with the true camera and plane pose.)",
         sim_photo},
        {"sim measurements",
         "synthetic delta measurements from the twin's truth",
         {scenario,
          {"--features", "N", "features over the bed (default 150)"},
          {"--noise", "MM", "Gaussian noise on each (default 0.01)"},
          {"--seed", "N", "the noise's seed"},
          {"-o", "measurements.json", "the measurements, written", Given::required},
          {"--probe", "heights.csv", "the nozzle's height over the bed at 37 points, written"}},
         R"(Synthetic measurements of a delta scenario, straight from the twin's truth: N features
(default 150) commanded over the bed at z = 0.2 and where they really landed, with Gaussian
noise (default 0.01 mm), three 60 mm bars along the towers, and with --probe the nozzle's
height over the bed at 37 points. For testing calbox solve without photos.)",
         sim_measurements},
        {"sim camera",
         "the scenario's true camera",
         {scenario, {"-o", "camera.yaml", "the camera, written", Given::required}},
         R"(The scenario's true camera as camera.yaml, for runs where calibration is not the point.)",
         sim_camera},
        {"sim verify",
         "the twin's judgement of its machine, before and after a result",
         {scenario,
          {"--result", "result.json", "a solve's result, sent to the twin's machine first"},
          {"-o", "verify.json", "the figures, written"}},
         R"(Judges a delta scenario's printer in the twin's truth, over the printable area: commanded
against actual XY (after the best rotation and translation) and the bed's height range;
with --result, again after sending that solve result's firmware lines and homing. A galvo
scenario's scanner: a fresh 30 x 30 grid of marks over the table's area (without --result,
the field less a pitch) burned as commanded, and with --result through its table: where
they land against where they were meant (rotation and translation taken out). A router
scenario: a fresh job of holes half a pitch off its target's, drilled as commanded and
with --result through the compensated G-code (calbox compensate's correction), each hole
against where it was meant (the work's zero and heading taken out).)",
         sim_verify},
    };
}

}  // namespace calbox::cli
