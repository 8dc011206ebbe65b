// Inputs other people's cameras made (CALBOX_TEST_DATA/realworld, each folder's source, licence
// and reference values in its README), through the same calls the command line makes.
#include <CppUTest/TestHarness.h>
#include <fnmatch.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/drawings/drawing.hpp"
#include "core/geometry/calibration.hpp"
#include "core/jobs/compensate.hpp"
#include "core/jobs/gcode_line.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_file.hpp"
#include "core/models/machine_import.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/modes/record_error.hpp"
#include "core/number_text.hpp"
#include "core/vision/image_codec.hpp"
#include "tests/support/gcode_reference.hpp"
#include "tests/support/test_data.hpp"

using namespace calbox;

namespace {

struct PhotoSet {
    std::vector<cv::Mat> images;
    std::vector<geometry::NamedImage> named;
};

PhotoSet photos_in(const std::string& folder) {
    std::vector<std::string> paths;
    for (const auto& e : std::filesystem::directory_iterator(test::test_data_path(folder)))
        if (e.path().extension() == ".jpg") paths.push_back(e.path().string());
    std::sort(paths.begin(), paths.end());
    PhotoSet set;
    for (const auto& p : paths) set.images.push_back(cv::imread(p, cv::IMREAD_GRAYSCALE));
    for (std::size_t i = 0; i < paths.size(); ++i) {
        const cv::Mat& m = set.images[i];
        set.named.push_back({std::filesystem::path(paths[i]).filename().string(),
                             {m.data, m.cols, m.rows, static_cast<int>(m.step)}});
    }
    return set;
}

// BoofCV's sets: chessboards of 5 x 7 squares (4 x 6 inner corners), 30 mm (the fisheye's in
// units of one square, which scales only the poses).
const geometry::PatternSpec kBoofBoard = geometry::parse_pattern_spec("chessboard:4x6@30");

geometry::CalibrationResult calibrate(const std::string& folder, geometry::LensModel model) {
    const auto set = photos_in("realworld/camera_calib/" + folder);
    return geometry::calibrate_camera(kBoofBoard, model, set.named);
}

void print(const char* what, const geometry::CalibrationResult& r) {
    const auto& c = r.camera;
    UT_PRINT((std::string(what) + ": fx " + std::to_string(c.fx()) + " fy " +
              std::to_string(c.fy()) + " cx " + std::to_string(c.cx()) + " cy " +
              std::to_string(c.cy()) + ", RMS " + std::to_string(c.rms_px) + " px over " +
              std::to_string(r.views.size()) + " views, " + std::to_string(r.dropped.size()) +
              " dropped")
                 .c_str());
}

}  // namespace

// The bounds: the focal lengths within 1.5 % of the folder's reference and the principal point
// within 6 px. Calibrations of one camera by two programs from one photo set differ by about a
// percent (on the Sony set OpenCV's own calibrateCamera gives 707.9 / 705.2 against BoofCV's
// 701.0 / 698.7); a wrong board size or corner order is off by far more.
TEST_GROUP(RealCamera){};

// Other people's cameras' JPEGs (EXIF, thumbnails, a fisheye's) read by the box's own reader as
// OpenCV reads them, pixel for pixel (the box's binary no longer links OpenCV's imgcodecs).
TEST(RealCamera, every_photo_reads_as_opencv_reads_it) {
    int read = 0;
    for (const auto& e :
         std::filesystem::recursive_directory_iterator(test::test_data_path("realworld"))) {
        const auto ext = e.path().extension().string();
        if (ext != ".jpg" && ext != ".png") continue;
        std::ifstream in(e.path(), std::ios::binary);
        const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                              std::istreambuf_iterator<char>());
        const cv::Mat theirs = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
        const auto ours = vision::decode_gray(bytes);
        CHECK_EQUAL(theirs.cols, ours.width_px);
        CHECK_EQUAL(theirs.rows, ours.height_px);
        const cv::Mat view(ours.height_px, ours.width_px, CV_8UC1,
                           const_cast<std::uint8_t*>(ours.pixels.data()));
        CHECK_TEXT(cv::norm(theirs, view, cv::NORM_INF) == 0, e.path().string().c_str());
        ++read;
    }
    CHECK_EQUAL(50, read);
}

TEST(RealCamera, bumblebee2_left_calibrates_near_its_published_intrinsics) {
    const auto r = calibrate("boofcv_bumblebee2_left_chess", geometry::LensModel::pinhole);
    print("bumblebee2 left", r);
    CHECK_EQUAL(11u, r.views.size());
    DOUBLES_EQUAL(524.61, r.camera.fx(), 524.61 * 0.015);
    DOUBLES_EQUAL(526.92, r.camera.fy(), 526.92 * 0.015);
    DOUBLES_EQUAL(312.45, r.camera.cx(), 6);
    DOUBLES_EQUAL(247.40, r.camera.cy(), 6);
    CHECK(r.camera.rms_px < 0.3);
}

TEST(RealCamera, sony_hx5v_calibrates_near_boofcvs_intrinsics) {
    const auto r = calibrate("boofcv_sony_hx5v_chess", geometry::LensModel::pinhole);
    print("sony hx5v", r);
    CHECK_EQUAL(13u, r.views.size());
    DOUBLES_EQUAL(701.01, r.camera.fx(), 701.01 * 0.015);
    DOUBLES_EQUAL(698.65, r.camera.fy(), 698.65 * 0.015);
    DOUBLES_EQUAL(308.46, r.camera.cx(), 6);
    DOUBLES_EQUAL(246.84, r.camera.cy(), 6);
    CHECK(r.camera.rms_px < 0.3);
}

// The set that wrote a 37.5 px camera file: two views (4.jpg, 5.jpg) far off the other 22.
TEST(RealCamera, fisheye_set_drops_the_two_views_far_off_and_calibrates_under_half_a_pixel) {
    const auto r = calibrate("boofcv_fisheye_chess", geometry::LensModel::fisheye);
    print("fisheye", r);
    CHECK(r.camera.rms_px < 0.5);
    std::vector<std::string> dropped;
    for (const auto& d : r.dropped) dropped.push_back(d.name);
    std::sort(dropped.begin(), dropped.end());
    CHECK((dropped == std::vector<std::string>{"4.jpg", "5.jpg"}));
    CHECK_EQUAL(22u, r.views.size());
    for (const auto& v : r.views) CHECK_TEXT(v.rms_px < 1.0, v.name.c_str());
    // Each reason names the view's figure against the others'.
    CHECK(r.dropped.front().why.find("against the better views'") != std::string::npos);
}

// 22.jpg: the board seen edge-on at the fisheye's rim, bright screens beside it. SB finds no
// board; the search through the equalised image (for a board under a glare) put a 4x6 grid across
// the wrong squares there, and that view stopped OpenCV's fisheye calibration. The board is not
// under a glare, so that search's find is not taken.
TEST(RealCamera, a_view_beside_bright_screens_gives_no_board_made_up_by_equalising) {
    const cv::Mat photo =
        cv::imread(test::test_data_path("realworld/camera_calib/boofcv_fisheye_chess/22.jpg"),
                   cv::IMREAD_GRAYSCALE);
    CHECK_FALSE(photo.empty());
    const auto found = geometry::find_board(
        kBoofBoard, {photo.data, photo.cols, photo.rows, static_cast<int>(photo.step)});
    CHECK_FALSE(found.has_value());
}

TEST(RealCamera, a_pinhole_model_on_the_fisheye_lens_is_refused_for_its_rms) {
    try {
        calibrate("boofcv_fisheye_chess", geometry::LensModel::pinhole);
        FAIL("a pinhole calibration of a fisheye lens was accepted");
    } catch (const geometry::CalibrationError& e) {
        const std::string why = e.what();
        CHECK_TEXT(why.find("pinhole calibration reprojects at") != std::string::npos, e.what());
        CHECK_TEXT(why.find("at most 1.00 px") != std::string::npos, e.what());
    }
}

TEST(RealCamera, too_few_views_left_once_the_far_ones_are_dropped_is_refused) {
    auto set = photos_in("realworld/camera_calib/boofcv_fisheye_chess");
    std::vector<geometry::NamedImage> four;
    for (const auto& n : set.named)
        if (n.name == "4.jpg" || n.name == "5.jpg" || n.name == "6.jpg" || n.name == "7.jpg")
            four.push_back(n);
    CHECK_EQUAL(4u, four.size());
    try {
        geometry::calibrate_camera(kBoofBoard, geometry::LensModel::fisheye, four);
        FAIL("two views were enough for a fisheye");
    } catch (const geometry::CalibrationError& e) {
        const std::string why = e.what();
        CHECK_TEXT(why.find("set aside") != std::string::npos, e.what());
        CHECK_TEXT(why.find("at least 4 views") != std::string::npos, e.what());
    }
}

// G-code other people's slicers and CAM programs wrote (realworld/gcode), through a correction
// a little off the identity: each file compensated, or refused for a reason a CAM user reads.
TEST_GROUP(RealGcode){};

namespace {

const jobs::Correction kSlightlyOff = [](geometry::Point2 p) {
    return geometry::Point2{1.001 * p.x + 0.0005 * p.y + 0.1, -0.0004 * p.x + 0.999 * p.y - 0.05};
};

// Each file in its controller's flavour, its work zero at `work_zero_mm` on the machine, no
// travel limit, the correction everywhere.
jobs::JobFrame frame_of_file(const std::string& file, geometry::Point2 work_zero_mm = {}) {
    const bool printer = file.rfind("printer/", 0) == 0;
    const bool ngc = file.size() > 4 && file.substr(file.size() - 4) == ".ngc";
    return {
        printer ? jobs::Flavour::printer : (ngc ? jobs::Flavour::linuxcnc : jobs::Flavour::grbl),
        {work_zero_mm},
        {},
        {}};
}

// A line the compensator moves: one with X or Y (or an arc's words) under a motion command.
// Everything else must come out as it went in, in order (line numbers aside).
bool is_xy_motion(const std::string& raw) {
    gcode::Line line;
    try {
        line = gcode::parse_line(raw);
    } catch (const gcode::SyntaxError&) {
        return false;
    }
    if (line.command_letter == 'M' || line.command_letter == 'T') return false;
    for (const int g : {4, 10, 28, 30, 53, 92})
        if (line.is('G', g)) return false;
    if (line.command_letter == 'G' && line.command_subcode >= 0) return false;
    return line.has('X') || line.has('Y') || line.has('I') || line.has('J') || line.has('R');
}

std::string without_number(std::string raw) {
    while (!raw.empty() && (raw.back() == '\r' || raw.back() == ' ')) raw.pop_back();
    raw = std::string(gcode::without_checksum(raw));
    std::size_t i = raw.find_first_not_of(" \t");
    if (i != std::string::npos && (raw[i] == 'N' || raw[i] == 'n')) {
        ++i;
        while (i < raw.size() && std::isdigit(static_cast<unsigned char>(raw[i]))) ++i;
        while (i < raw.size() && raw[i] == ' ') ++i;
        raw = raw.substr(i);
    }
    while (!raw.empty() && raw.back() == ' ') raw.pop_back();
    return raw;
}

std::vector<std::string> kept_lines(const std::string& text, bool output) {
    std::vector<std::string> kept;
    std::istringstream in(text);
    for (std::string raw; std::getline(in, raw);) {
        if (output) {
            const auto line = gcode::parse_line(raw);
            const bool written_move =
                (line.is('G', 0) || line.is('G', 1) ||
                 (line.command_letter == 'G' && !line.parameters.empty() &&
                  std::any_of(line.parameters.begin(), line.parameters.end(),
                              [](const gcode::Word& w) {
                                  return w.letter == 'G' && w.value && *w.value <= 1;
                              }))) &&
                (line.has('X') || line.has('Y'));
            if (written_move) continue;
        } else if (is_xy_motion(raw)) {
            continue;
        }
        kept.push_back(without_number(raw));
    }
    return kept;
}

}  // namespace

TEST(RealGcode, every_file_is_compensated_or_refused_for_a_reason_a_cam_user_reads) {
    // What each file is: compensated (""), or refused with these words.
    const std::map<std::string, std::string> expected = {
        {"cnc/fusion360/1070_wall_27bit.nc", ""},
        {"cnc/jsdc.gcode", ""},
        {"cnc/linuxcnc/arcspiral.ngc", ""},
        {"cnc/linuxcnc/g76.ngc", "a lathe job"},
        {"cnc/linuxcnc/hole-circle.ngc", ""},
        {"cnc/linuxcnc/tort.ngc", ""},
        {"cnc/ugs/ShapeOko_Calibration_Pattern_01b.ngc", ""},
        {"cnc/ugs/arc_rword_test.gcode", ""},
        {"laser/input5.gcode", ""},
        {"printer/gcode-preview_plant-sign_prusaslicer274_arcs.gcode", ""},
        {"printer/gcode-preview_puzzle_all_cura231.gcode", ""},
        {"printer/gcode-preview_vase_prusaslicer274.gcode", ""},
    };
    int compensated = 0, refused = 0;
    for (const auto& [file, refusal] : expected) {
        const std::string job = test::read_test_data("realworld/gcode/" + file);
        jobs::CompensateReport report;
        std::string out, why;
        try {
            out = jobs::compensate_gcode(job, {kSlightlyOff, {}}, frame_of_file(file), {}, report);
        } catch (const jobs::CompensateError& e) {
            why = e.what();
        }
        UT_PRINT((file + ": " +
                  (why.empty() ? "compensated, " + std::to_string(report.moves) + " moves, " +
                                     std::to_string(report.arcs) + " arcs"
                               : "refused: " + why))
                     .c_str());
        if (why.empty()) {
            ++compensated;
            CHECK_TEXT(refusal.empty(), file.c_str());
            // Every non-motion line kept, in order (a program LinuxCNC evaluates, or one whose
            // drilling cycles repeat, is checked hole by hole on its own).
            if (report.ran_program || report.holes > 0) continue;
            const auto in = kept_lines(job, false), kept = kept_lines(out, true);
            CHECK_TEXT(in == kept, (file + ": " + std::to_string(in.size()) + " lines in, " +
                                    std::to_string(kept.size()) + " kept")
                                       .c_str());
        } else {
            ++refused;
            CHECK_TEXT(!refusal.empty() && why.find(refusal) != std::string::npos, why.c_str());
        }
    }
    UT_PRINT((std::to_string(compensated) + " compensated, " + std::to_string(refused) + " refused")
                 .c_str());
}

// Drawings other people made (realworld/svg), as a job for a laser and as librsvg (a browser's
// renderer, from Debian) paints them: the job's lines lie on what is painted, and what is painted
// lies near the job's lines, within 1 % of the drawing's size and the widest stroke's width.
TEST_GROUP(RealSvg){};

namespace {

const char* kLaserToml = R"toml(
[machine]
kind = "laser"
firmware = "grbl"
bed_size_x_mm = 300.0
bed_size_y_mm = 300.0
tool_width_mm = 0.2
)toml";

struct Painted {
    cv::Mat mask;  // 255 where painted
    cv::Rect box;
};

Painted as_librsvg_paints(const std::string& svg_path, const std::string& png_path) {
    const std::string command =
        "rsvg-convert -w 600 -a -o '" + png_path + "' '" + svg_path + "' 2>/dev/null";
    if (std::system(command.c_str()) != 0) FAIL(("rsvg-convert failed on " + svg_path).c_str());
    const cv::Mat rgba = cv::imread(png_path, cv::IMREAD_UNCHANGED);
    std::vector<cv::Mat> channels;
    cv::split(rgba, channels);
    Painted p;
    // Any coverage counts: a stroke under a pixel wide is painted at partial alpha.
    p.mask = channels.size() == 4 ? channels[3] > 31 : cv::Mat(rgba.size(), CV_8U, 255);
    p.box = cv::boundingRect(p.mask);
    return p;
}

// The share of `a`'s pixels farther than `reach_px` from any of `b`'s.
double share_beyond(const cv::Mat& a, const cv::Mat& b, double reach_px) {
    cv::Mat distance;
    cv::distanceTransform(~b, distance, cv::DIST_L2, 3);
    const cv::Mat far = (distance > reach_px) & a;
    return static_cast<double>(cv::countNonZero(far)) / std::max(1, cv::countNonZero(a));
}

}  // namespace

TEST(RealSvg, every_drawing_gives_a_job_on_the_drawing_as_a_browser_paints_it) {
    const auto machine = models::parse_machine_file(kLaserToml, "laser.toml");
    // What each file is: a job (""), or refused with these words.
    const std::map<std::string, std::string> expected = {
        {"nanosvg/23.svg", ""},
        {"svgpathtools/circle.svg", ""},
        {"svgpathtools/ellipse.svg", ""},
        {"svgpathtools/groups.svg", ""},
        {"svgpathtools/negative-scale.svg", ""},
        {"svgpathtools/polygons.svg", ""},
        {"svgpathtools/rects.svg", ""},
        {"svgpathtools/test.svg", ""},
        {"svgpathtools/transforms.svg", ""},
        {"svgpathtools/zero-radius-arcs.svg", ""},
    };
    // Drawings made for this test in Illustrator's manner (a CSS sheet of classes, <use>, text in
    // two faces) and Inkscape's (layers, <symbol>, a clip path over strokes, a marker, a tspan).
    const std::vector<std::string> ours = {"illustrator_badge.svg", "inkscape_gauge.svg"};
    std::vector<std::pair<std::string, std::string>> drawings;  // path, refusal
    for (const auto& [file, refusal] : expected)
        drawings.emplace_back(test::test_data_path("realworld/svg/" + file), refusal);
    for (const auto& file : ours)
        drawings.emplace_back(std::string(CALBOX_SOURCE_DIR) + "/tests/drawings/" + file, "");
    const std::string png = (std::filesystem::temp_directory_path() /
                             ("calbox_realsvg_" + std::to_string(::getpid()) + ".png"))
                                .string();
    for (const auto& [path, refusal] : drawings) {
        const std::string file = std::filesystem::path(path).filename().string();
        const std::string text = test::read_whole_file(path);
        jobs::PlacedJob job;
        std::string why;
        try {
            jobs::SvgJobSettings settings;
            settings.fit_mm = 100;
            job = jobs::plan_svg_job(drawings::read_drawing(text), machine, settings);
        } catch (const std::exception& e) {
            why = e.what();
        }
        if (!why.empty()) {
            UT_PRINT((file + ": refused: " + why).c_str());
            CHECK_TEXT(!refusal.empty() && why.find(refusal) != std::string::npos, why.c_str());
            continue;
        }
        CHECK_TEXT(refusal.empty(), (file + " was not refused").c_str());
        const Painted painted = as_librsvg_paints(path, png);
        // librsvg paints the page (the document's viewport) 600 px wide: the job's lines are
        // drawn on that frame through the job's own placement, taken back to the document. A
        // document without a page (no width or height) is painted over its content's extent:
        // the job's lines are then drawn on the painted extent.
        const auto document = drawings::read_drawing(text);
        const bool has_page = document.width_mm > 0 && document.height_mm > 0;
        double min_x = 1e300, max_x = -1e300, min_y = 1e300, max_y = -1e300;
        for (const auto& m : job.toolpath.moves) {
            if (m.kind == targets::MoveKind::travel) continue;
            for (const auto& p : {m.from, m.to}) {
                min_x = std::min(min_x, p.x), max_x = std::max(max_x, p.x);
                min_y = std::min(min_y, p.y), max_y = std::max(max_y, p.y);
            }
        }
        const double px_per_mm = has_page
                                     ? 600 / document.width_mm
                                     : std::max(painted.box.width, painted.box.height) /
                                           (std::max(max_x - min_x, max_y - min_y) / job.scale);
        cv::Mat lines = cv::Mat::zeros(painted.mask.size(), CV_8U);
        const auto at = [&](geometry::Point2 p) {
            if (!has_page)
                return cv::Point(static_cast<int>(std::lround(
                                     painted.box.x + (p.x - min_x) / job.scale * px_per_mm)),
                                 static_cast<int>(std::lround(
                                     painted.box.y + (max_y - p.y) / job.scale * px_per_mm)));
            const double x = job.drawing_min.x + (p.x - job.min_x) / job.scale;
            const double y = job.drawing_min.y + (job.max_y - p.y) / job.scale;
            return cv::Point(static_cast<int>(std::lround(x * px_per_mm - 0.5)),
                             static_cast<int>(std::lround(y * px_per_mm - 0.5)));
        };
        const int thickness =
            std::max(1, static_cast<int>(std::lround(job.line_width_mm / job.scale * px_per_mm)));
        for (const auto& m : job.toolpath.moves)
            if (m.kind != targets::MoveKind::travel)
                cv::line(lines, at(m.from), at(m.to), 255, thickness);
        // A stroke is painted its width across, the job traces its middle: the reach takes in
        // the widest stroke whole (a group's uneven scale widens it one way).
        double widest_stroke_mm = 0;
        for (const auto& shape : document.shapes)
            if (shape.stroked) widest_stroke_mm = std::max(widest_stroke_mm, shape.stroke_width_mm);
        const double reach_px = 0.01 * std::max(painted.box.width, painted.box.height) + 2 +
                                widest_stroke_mm * px_per_mm;
        const double job_off = share_beyond(lines, painted.mask, reach_px);
        const double painted_off = share_beyond(painted.mask, lines, reach_px);
        UT_PRINT((file + ": " +
                  number_text("%.2f %% of the job's line off the painting, ", 100 * job_off) +
                  number_text("%.2f %% of the painting away from the job", 100 * painted_off))
                     .c_str());
        // The issue's bar is 0.5 %; read through librsvg itself, every drawing is under 0.1 %.
        CHECK_TEXT(job_off < 0.001 && painted_off < 0.001, file.c_str());
    }
    std::filesystem::remove(png);
}

// Printers' own files (realworld/firmware_console): each imports as a machine file, its
// geometry read as the folder's README gives it.
TEST_GROUP(RealImport){};

namespace {

const std::string kConsole = "realworld/firmware_console/";

models::ReadIncluded from_test_data() {
    return [](const std::string& path) -> std::optional<std::string> {
        try {
            return test::read_test_data(path.substr(test::test_data_path("").size()));
        } catch (const std::runtime_error&) {
            return std::nullopt;
        }
    };
}

// The machine file written reads back, with the same geometry.
void reads_back(const models::ImportedMachine& imported) {
    const auto again = models::parse_machine_file(models::machine_file_text(imported), "import");
    CHECK_EQUAL(imported.machine.kind, again.kind);
    if (!imported.machine.delta) return;
    const auto& a = *imported.machine.delta;
    const auto& b = *again.delta;
    DOUBLES_EQUAL(a.diagonal_rod_mm, b.diagonal_rod_mm, 1e-6);
    DOUBLES_EQUAL(a.radius_mm, b.radius_mm, 1e-6);
    DOUBLES_EQUAL(a.height_mm, b.height_mm, 1e-6);
    for (std::size_t i = 0; i < 3; ++i) {
        DOUBLES_EQUAL(a.tower_angle_trim_deg[i], b.tower_angle_trim_deg[i], 1e-6);
        DOUBLES_EQUAL(a.endstop_offset_mm[i], b.endstop_offset_mm[i], 1e-6);
        DOUBLES_EQUAL(a.diagonal_rod_trim_mm[i], b.diagonal_rod_trim_mm[i], 1e-6);
    }
}

}  // namespace

TEST(RealImport, klipper_flsun_q5_reads_its_save_config_block_over_the_sections) {
    const std::string path = test::test_data_path(
        kConsole + "klipper_delta/flsun_q5_razorcopter/printer_post_calibration.cfg");
    const std::string text = test::read_test_data(
        kConsole + "klipper_delta/flsun_q5_razorcopter/printer_post_calibration.cfg");
    const auto config = models::read_klipper_config(path, text, from_test_data());
    DOUBLES_EQUAL(101.288849, config.delta.delta_radius_mm, 1e-6);
    const double angles[3] = {210.481232, 330.925002, 90};
    const double arms[3] = {217.6266, 216.0959, 215.7964};
    const double endstops[3] = {218.724820, 219.438345, 218.763895};
    for (std::size_t i = 0; i < 3; ++i) {
        DOUBLES_EQUAL(angles[i], config.delta.angle_deg[i], 1e-6);
        DOUBLES_EQUAL(arms[i], config.delta.arm_length_mm[i], 1e-6);
        DOUBLES_EQUAL(endstops[i], config.delta.position_endstop_mm[i], 1e-6);
    }
    // fluidd.cfg, which it includes, is not in the folder: said, not fatal.
    CHECK_EQUAL(1u, config.notes.size());
    const auto imported = models::import_klipper(path, text, from_test_data(), {});
    DOUBLES_EQUAL(105, imported.machine.bed_radius_mm, 1e-9);  // [printer] print_radius
    reads_back(imported);
    // The file before calibration has delta_radius commented out: Klipper itself refuses it
    // ("must be specified"), and so does the import, naming the key.
    const std::string before_path = test::test_data_path(
        kConsole + "klipper_delta/flsun_q5_razorcopter/printer_pre_calibration.cfg");
    try {
        models::read_klipper_config(
            before_path,
            test::read_test_data(kConsole + "klipper_delta/flsun_q5_razorcopter/"
                                            "printer_pre_calibration.cfg"),
            from_test_data());
        FAIL("a printer.cfg without delta_radius imported");
    } catch (const models::ImportError& e) {
        STRCMP_CONTAINS("no delta_radius in [printer]", e.what());
    }
}

TEST(RealImport, a_printer_cfg_whose_includes_loop_is_refused_naming_the_loop) {
    const std::map<std::string, std::string> files = {
        {"cfg/b.cfg", "[include a.cfg]\n"},
        {"cfg/a.cfg", "[include b.cfg]\n[printer]\nkinematics: delta\n"}};
    const models::ReadIncluded read = [&](const std::string& p) -> std::optional<std::string> {
        const auto it = files.find(p);
        return it == files.end() ? std::nullopt : std::optional<std::string>(it->second);
    };
    try {
        models::read_klipper_config("cfg/a.cfg", files.at("cfg/a.cfg"), read);
        FAIL("an include loop was read");
    } catch (const models::ImportError& e) {
        STRCMP_CONTAINS("includes loop: cfg/a.cfg -> cfg/b.cfg -> cfg/a.cfg", e.what());
    }
}

TEST(RealImport, a_wildcard_include_reads_every_match_in_klippers_sorted_order) {
    // Two parts set the same key: the later in sorted order wins, as Klipper reads them.
    const std::map<std::string, std::string> files = {
        {"cfg/printer.cfg", "[include parts/*.cfg]\n[printer]\nkinematics: delta\n"},
        {"cfg/parts/b_towers.cfg", "[printer]\ndelta_radius: 101.5\n"},
        {"cfg/parts/a_frame.cfg", "[printer]\ndelta_radius: 99\nprint_radius: 90\n"},
        {"cfg/other/z.cfg", "[printer]\ndelta_radius: 1\n"}};
    const models::ReadIncluded read = [&](const std::string& p) -> std::optional<std::string> {
        const auto it = files.find(p);
        return it == files.end() ? std::nullopt : std::optional<std::string>(it->second);
    };
    std::vector<std::string> asked;
    const models::ListIncluded list = [&](const std::string& pattern) {
        asked.push_back(pattern);
        std::vector<std::string> found;
        for (auto it = files.rbegin(); it != files.rend(); ++it)  // not sorted: the reader sorts
            if (::fnmatch(pattern.c_str(), it->first.c_str(), FNM_PATHNAME) == 0)
                found.push_back(it->first);
        return found;
    };
    std::vector<std::string> notes;
    const auto sections = models::read_klipper_sections(
        "cfg/printer.cfg", files.at("cfg/printer.cfg"), read, notes, list);
    CHECK_EQUAL(1u, asked.size());
    STRCMP_EQUAL("cfg/parts/*.cfg", asked[0].c_str());
    STRCMP_EQUAL("101.5", sections.at("printer").at("delta_radius").c_str());
    STRCMP_EQUAL("90", sections.at("printer").at("print_radius").c_str());
    CHECK_TRUE(notes.empty());
    // A wildcard naming nothing is no error (Klipper's rule); without a way to list, it is said.
    notes.clear();
    models::read_klipper_sections("cfg/x.cfg", "[include none/*.cfg]\n", read, notes, list);
    CHECK_TRUE(notes.empty());
    models::read_klipper_sections("cfg/x.cfg", "[include parts/*.cfg]\n", read, notes);
    CHECK_EQUAL(1u, notes.size());
    STRCMP_CONTAINS("cfg/parts/*.cfg (included, a wildcard) cannot be listed here",
                    notes[0].c_str());
}

TEST(RealImport, reprapfirmware_deltas_read_config_override_over_config) {
    const std::string kossel = kConsole + "rrf_delta/kossel250vs_gaelreinaudi/";
    const auto config =
        models::read_rrf_config({test::read_test_data(kossel + "config.g"),
                                 test::read_test_data(kossel + "config-override.g")});
    const auto m665 = gcode::parse_line(*config.m665);
    const auto m666 = gcode::parse_line(*config.m666);
    const auto rods = m665.values('L');
    CHECK_EQUAL(3u, rods.size());
    for (const double rod : rods) DOUBLES_EQUAL(288.280, rod, 1e-9);
    DOUBLES_EQUAL(170.909, *m665.value('R'), 1e-9);
    DOUBLES_EQUAL(226.861, *m665.value('H'), 1e-9);
    DOUBLES_EQUAL(-0.095, *m665.value('X'), 1e-9);
    DOUBLES_EQUAL(0.274, *m665.value('Y'), 1e-9);
    DOUBLES_EQUAL(0.143, *m666.value('X'), 1e-9);
    DOUBLES_EQUAL(0.118, *m666.value('Y'), 1e-9);
    DOUBLES_EQUAL(-0.261, *m666.value('Z'), 1e-9);
    const auto imported = models::import_rrf({test::read_test_data(kossel + "config.g"),
                                              test::read_test_data(kossel + "config-override.g")},
                                             {});
    DOUBLES_EQUAL(120, imported.machine.bed_radius_mm, 1e-9);  // M665 B
    reads_back(imported);
    const std::string anycubic = kConsole + "rrf_delta/anycubic_kossel_citruspers/";
    const auto other =
        models::read_rrf_config({test::read_test_data(anycubic + "config.g"),
                                 test::read_test_data(anycubic + "config-override.g")});
    const auto l = gcode::parse_line(*other.m665);
    DOUBLES_EQUAL(271.5, *l.value('L'), 1e-9);
    DOUBLES_EQUAL(134.67, *l.value('R'), 1e-9);
    DOUBLES_EQUAL(290, *l.value('H'), 1e-9);
    reads_back(models::import_rrf({test::read_test_data(anycubic + "config.g"),
                                   test::read_test_data(anycubic + "config-override.g")},
                                  {}));
}

TEST(RealImport, marlin_g33_reports_and_m503_captures) {
    const std::string page =
        test::read_test_data(kConsole + "marlin_delta/marlindocs_G033_sample_output.md");
    // Marlin's documentation page: its first example, the V1 run, ends at height 297.80, Ex -0.14
    // Ey -0.07, radius 100.79, tower angles -0.10 / +0.22.
    const auto first = page.find("> G33");
    const auto second = page.find("> G33", first + 5);
    const auto v1 = models::read_marlin_capture(page.substr(first, second - first));
    CHECK(v1.delta && v1.delta->from_g33);
    DOUBLES_EQUAL(297.80, *v1.delta->height_mm, 1e-9);
    DOUBLES_EQUAL(100.79, *v1.delta->radius_mm, 1e-9);
    DOUBLES_EQUAL(-0.14, v1.delta->endstop_mm[0], 1e-9);
    DOUBLES_EQUAL(-0.07, v1.delta->endstop_mm[1], 1e-9);
    DOUBLES_EQUAL(-0.10, v1.delta->angle_trim_deg[0], 1e-9);
    DOUBLES_EQUAL(0.22, v1.delta->angle_trim_deg[1], 1e-9);
    // G33 leaves the rod out: asked for.
    try {
        models::import_marlin(page, {});
        FAIL("a G33 report imported without its rod");
    } catch (const models::ImportError& e) {
        STRCMP_CONTAINS("give --diagonal-rod", e.what());
    }
    models::ImportOptions rod;
    rod.diagonal_rod_mm = 218;
    reads_back(models::import_marlin(page, rod));
    // OctoPrint's wrapped M503 of a cartesian printer: M92 X200 Y200.
    const auto cartesian = models::import_marlin(
        test::read_test_data(kConsole + "marlin_cartesian_m503/tmc_response.gcode"), {});
    CHECK_EQUAL(std::string("cartesian"), cartesian.machine.kind);
    DOUBLES_EQUAL(200, *cartesian.machine.planar->steps_per_mm_x, 1e-9);
    DOUBLES_EQUAL(200, *cartesian.machine.planar->steps_per_mm_y, 1e-9);
    reads_back(cartesian);
    // A fragment of M503 with neither: refused, saying what to capture.
    try {
        models::import_marlin(
            test::read_test_data(kConsole + "marlin_cartesian_m503/issue33_debug.gcode"), {});
        FAIL("a capture without geometry imported");
    } catch (const models::ImportError& e) {
        STRCMP_CONTAINS("capture the printer's whole reply to M503", e.what());
    }
}

TEST(RealImport, a_marlin_cartesian_with_dual_z_endstops_is_a_cartesian) {
    // M503 of a cartesian built with Z_MULTI_ENDSTOPS, as Marlin 2.1 prints it: M666 adjusts the
    // second Z endstop; there is no M665.
    const std::string capture =
        "echo:; Steps per unit:\n"
        "echo:  M92 X80.00 Y80.00 Z400.00 E93.00\n"
        "echo:; Endstop adjustment:\n"
        "echo:  M666 Z-0.15\n";
    const auto imported = models::import_marlin(capture, {});
    STRCMP_EQUAL("cartesian", imported.machine.kind.c_str());
    DOUBLES_EQUAL(80, *imported.machine.planar->steps_per_mm_x, 1e-9);
    CHECK_TRUE(std::any_of(imported.notes.begin(), imported.notes.end(), [](const auto& n) {
        return n.find("M666 without M665: its dual endstops' adjustments") != std::string::npos;
    }));
    reads_back(imported);
    // M666 alone is no delta either: refused, saying what it is.
    try {
        models::import_marlin("echo:  M666 Z-0.15\n", {});
        FAIL("a lone M666 imported");
    } catch (const models::ImportError& e) {
        STRCMP_CONTAINS("its M666 alone is a cartesian's dual endstops", e.what());
    }
}

// RepRapFirmware's measured height map (anycubic_kossel_citruspers/heightmap.csv: 7 x 7 at 30 mm,
// radius 110, "mean error -0.017, deviation 0.061") as the probe file `solve delta --probe` takes.
TEST(RealImport, an_rrf_height_map_is_a_probe_file_with_its_stated_mean_and_deviation) {
    const auto probe = modes::probe_from_file(
        test::read_test_data(kConsole + "rrf_delta/anycubic_kossel_citruspers/heightmap.csv"),
        "heightmap.csv");
    // The 7 x 7 grid's points within 110 mm of the centre: all but the four corners.
    CHECK_EQUAL(45u, probe.size());
    double sum = 0, sum2 = 0;
    for (const auto& p : probe) {
        CHECK(std::hypot(p.x_mm, p.y_mm) <= 110);
        sum += -p.z_mm;  // the map's heights are the gaps negated
        sum2 += p.z_mm * p.z_mm;
    }
    const double n = static_cast<double>(probe.size());
    const double mean = sum / n;
    const double deviation = std::sqrt(sum2 / n - mean * mean);
    DOUBLES_EQUAL(-0.017, mean, 0.0015);
    DOUBLES_EQUAL(0.061, deviation, 0.0015);
}

namespace {

// Segments by the cells of a grid they cross: the distance from a point to a path of tens of
// thousands of segments, in a few of them.
class PathIndex {
  public:
    explicit PathIndex(const std::vector<std::pair<geometry::Point2, geometry::Point2>>& segments)
        : segments_(segments) {
        for (std::size_t i = 0; i < segments_.size(); ++i) {
            const auto& [a, b] = segments_[i];
            for (long x = cell(std::min(a.x, b.x)); x <= cell(std::max(a.x, b.x)); ++x)
                for (long y = cell(std::min(a.y, b.y)); y <= cell(std::max(a.y, b.y)); ++y)
                    cells_[{x, y}].push_back(i);
        }
    }
    double distance(geometry::Point2 p) const {
        double best = 1e300;
        for (long dx = -1; dx <= 1; ++dx)
            for (long dy = -1; dy <= 1; ++dy) {
                const auto it = cells_.find({cell(p.x) + dx, cell(p.y) + dy});
                if (it == cells_.end()) continue;
                for (const std::size_t i : it->second) {
                    const auto& [a, b] = segments_[i];
                    const double vx = b.x - a.x, vy = b.y - a.y, len2 = vx * vx + vy * vy;
                    const double t =
                        len2 > 0
                            ? std::clamp(((p.x - a.x) * vx + (p.y - a.y) * vy) / len2, 0.0, 1.0)
                            : 0;
                    best = std::min(best, std::hypot(a.x + t * vx - p.x, a.y + t * vy - p.y));
                }
            }
        return best;
    }

  private:
    static long cell(double v) { return static_cast<long>(std::floor(v / kCellMm)); }
    static constexpr double kCellMm = 2;
    std::vector<std::pair<geometry::Point2, geometry::Point2>> segments_;
    std::map<std::pair<long, long>, std::vector<std::size_t>> cells_;
};

std::vector<std::pair<geometry::Point2, geometry::Point2>> segments_of(
    const std::vector<test::ReferenceMove>& moves, const jobs::Correction& through) {
    std::vector<std::pair<geometry::Point2, geometry::Point2>> out;
    for (const auto& m : moves)
        for (std::size_t k = 1; k < m.path_mm.size(); ++k)
            out.emplace_back(through(m.path_mm[k - 1]), through(m.path_mm[k]));
    return out;
}

}  // namespace

// The compensated files' motion against the input's motion sent through the correction, each
// read by the tests' own reading (tests/support/gcode_reference.hpp): every point the output
// reaches lies on the corrected input path, and every point of the input path, corrected, on the
// output's, within the compensator's own arc tolerance of 0.002 mm (and its 0.0001 mm digits).
TEST(RealGcode, a_compensated_files_motion_is_the_inputs_through_the_correction) {
    const jobs::Correction identity = [](geometry::Point2 p) { return p; };
    // Each job placed with its work zero at machine (40, -25): the correction is the machine's,
    // so the job's point p goes to kSlightlyOff(p + W) - W (not kSlightlyOff(p), which a job
    // compensated in the wrong frame would show, up to 0.05 mm off here).
    const geometry::Point2 w{40, -25};
    const jobs::Correction through_machine = [w](geometry::Point2 p) {
        const auto c = kSlightlyOff({p.x + w.x, p.y + w.y});
        return geometry::Point2{c.x - w.x, c.y - w.y};
    };
    double worst = 0;
    for (const char* file :
         {"cnc/fusion360/1070_wall_27bit.nc", "cnc/jsdc.gcode", "cnc/linuxcnc/arcspiral.ngc",
          "cnc/linuxcnc/tort.ngc", "cnc/ugs/ShapeOko_Calibration_Pattern_01b.ngc",
          "cnc/ugs/arc_rword_test.gcode", "laser/input5.gcode",
          "printer/gcode-preview_plant-sign_prusaslicer274_arcs.gcode",
          "printer/gcode-preview_puzzle_all_cura231.gcode",
          "printer/gcode-preview_vase_prusaslicer274.gcode"}) {
        const std::string job = test::read_test_data(std::string("realworld/gcode/") + file);
        jobs::CompensateReport report;
        const std::string out =
            jobs::compensate_gcode(job, {kSlightlyOff, {}}, frame_of_file(file, w), {}, report);
        const auto in_moves = test::reference_motion(job);
        const auto out_moves = test::reference_motion(out);
        const PathIndex input_corrected(segments_of(in_moves, through_machine));
        const PathIndex output(segments_of(out_moves, identity));
        double off_input = 0, off_output = 0;
        for (const auto& m : out_moves)
            for (std::size_t k = m.start_known ? 0 : 1; k < m.path_mm.size(); ++k)
                off_input = std::max(off_input, input_corrected.distance(m.path_mm[k]));
        for (const auto& m : in_moves)
            for (std::size_t k = m.start_known ? 0 : 1; k < m.path_mm.size(); ++k)
                off_output = std::max(off_output, output.distance(through_machine(m.path_mm[k])));
        UT_PRINT((std::string(file) + ": " + std::to_string(in_moves.size()) + " moves in, " +
                  std::to_string(out_moves.size()) + " out; the output off the corrected input " +
                  number_text("%.5f", off_input) + " mm, the corrected input off the output " +
                  number_text("%.5f", off_output) + " mm")
                     .c_str());
        worst = std::max({worst, off_input, off_output});
        CHECK_TEXT(off_input <= 0.0021 && off_output <= 0.0021, file);
    }
    UT_PRINT(("worst " + number_text("%.5f", worst) + " mm").c_str());
}

// LinuxCNC's hole-circle.ngc: six holes drilled round a 1.5 inch radius by an incremental G81
// repeated with polar words (G91 ... ^60 L6). Each hole, worked by hand at 60 k degrees on that
// circle about the work zero, comes out through the correction as LinuxCNC keeps the cycle.
TEST(RealGcode, a_bolt_circle_in_polar_words_drills_each_hole_through_the_correction) {
    const std::string job = test::read_test_data("realworld/gcode/cnc/linuxcnc/hole-circle.ngc");
    const geometry::Point2 w{150, 150};
    jobs::CompensateReport report;
    const std::string out = jobs::compensate_gcode(
        job, {kSlightlyOff, {}}, frame_of_file("cnc/linuxcnc/hole-circle.ngc", w), {}, report);
    CHECK_EQUAL(6, report.holes);
    std::istringstream lines(out);
    geometry::Point2 at_in{};  // the written position, inches, in the job's frame
    bool incremental = false;
    int hole = 0;
    for (std::string raw; std::getline(lines, raw);) {
        const auto line = gcode::parse_line(raw);
        bool g91 = line.is('G', 91), g90 = line.is('G', 90), g81 = line.is('G', 81);
        for (const auto& word : line.parameters)
            if (word.letter == 'G' && word.value) {
                g91 = g91 || *word.value == 91;
                g90 = g90 || *word.value == 90;
                g81 = g81 || *word.value == 81;
            }
        if (g91) incremental = true;
        if (g90) incremental = false;
        if (!line.has('X') && !line.has('Y')) continue;
        const double x = line.value('X').value_or(incremental ? 0 : at_in.x);
        const double y = line.value('Y').value_or(incremental ? 0 : at_in.y);
        at_in = incremental ? geometry::Point2{at_in.x + x, at_in.y + y} : geometry::Point2{x, y};
        if (!g81) continue;
        ++hole;
        const double a = hole * 60 * 3.14159265358979323846 / 180;
        const geometry::Point2 machine{1.5 * 25.4 * std::cos(a) + w.x,
                                       1.5 * 25.4 * std::sin(a) + w.y};
        const auto c = kSlightlyOff(machine);
        DOUBLES_EQUAL(c.x - w.x, at_in.x * 25.4, 0.002);
        DOUBLES_EQUAL(c.y - w.y, at_in.y * 25.4, 0.002);
    }
    CHECK_EQUAL(6, hole);
}

// Klipper's saved [delta_calibrate] probe (FLSUN Q5): its seven stepper positions (80 steps a mm,
// kept as steps below each endstop) through the geometry saved beside them. DELTA_CALIBRATE
// probes the centre and six points at 90 + 60 k degrees, 0.95, 0.90, 0.85, 0.70, 0.75 and 0.80 of
// its radius (Klipper's delta_calibrate.py): read back through the saved geometry, the points lie
// at those angles and at those radii times one common scale within 3 % (the probing was
// commanded through the geometry before the calibration, and the nozzle really was a few percent
// further out than commanded), and their gaps within a quarter of a millimetre (the extended
// calibration came after the heights were kept). A wrong reading of the positions (steps from
// zero instead of below the endstop) put the centre's gap at 21 mm.
TEST(RealImport, klippers_saved_delta_calibrate_heights_are_probe_points_in_their_geometry) {
    const std::string file =
        kConsole + "klipper_delta/flsun_q5_razorcopter/printer_post_calibration.cfg";
    const auto probe = modes::probe_from_file(test::read_test_data(file), file);
    CHECK_EQUAL(7u, probe.size());
    CHECK(std::hypot(probe[0].x_mm, probe[0].y_mm) < 2);
    const double scatter[6] = {0.95, 0.90, 0.85, 0.70, 0.75, 0.80};
    double low = probe[0].z_mm, high = probe[0].z_mm, scale_low = 1e9, scale_high = 0;
    for (std::size_t k = 1; k < 7; ++k) {
        const auto& p = probe[k];
        const double angle = std::atan2(p.y_mm, p.x_mm) * 180 / 3.14159265358979;
        const double expected = 90.0 + 60.0 * static_cast<double>(k - 1);
        const double off = std::remainder(angle - expected, 360.0);
        const double scale = std::hypot(p.x_mm, p.y_mm) / (100 * scatter[k - 1]);
        UT_PRINT((number_text("point %.0f: ", static_cast<double>(k)) +
                  number_text("%.2f deg off, ", off) + number_text("radius scale %.4f, ", scale) +
                  number_text("gap %.4f mm", p.z_mm))
                     .c_str());
        CHECK(std::abs(off) < 1.5);
        scale_low = std::min(scale_low, scale), scale_high = std::max(scale_high, scale);
        low = std::min(low, p.z_mm), high = std::max(high, p.z_mm);
    }
    CHECK(scale_high - scale_low < 0.03);
    CHECK(high - low < 0.25);
}

// Marlin's G33 at V2 (its documentation page's example): two probe blocks, then "rolling back" to
// the first geometry; the block measured under that geometry is the first one
// (c:+0.01 x:+0.06 y:+0.04 z:+0.01, yz:-0.02 zx:-0.01 xy:+0.01), at the radius given.
TEST(RealImport, a_marlin_g33_v2_report_is_a_probe_file_given_its_radius) {
    const std::string page =
        test::read_test_data(kConsole + "marlin_delta/marlindocs_G033_sample_output.md");
    const auto start = page.find("> G33 V2");
    const std::string run = page.substr(start, page.find("> G33", start + 5) - start);
    try {
        modes::probe_from_file(run, "g33.log");
        FAIL("a G33 report read without its radius");
    } catch (const modes::RecordError& e) {
        STRCMP_CONTAINS("give --probe-radius", e.what());
    }
    const auto probe = modes::probe_from_file(run, "g33.log", 80.0);
    CHECK_EQUAL(7u, probe.size());
    const double gaps[7] = {-0.01, -0.06, -0.04, -0.01, 0.02, 0.01, -0.01};
    const double angles[6] = {210, 330, 90, 30, 150, 270};
    DOUBLES_EQUAL(0, std::hypot(probe[0].x_mm, probe[0].y_mm), 1e-9);
    for (std::size_t i = 0; i < 7; ++i) DOUBLES_EQUAL(gaps[i], probe[i].z_mm, 1e-9);
    for (std::size_t i = 0; i < 6; ++i) {
        DOUBLES_EQUAL(80, std::hypot(probe[i + 1].x_mm, probe[i + 1].y_mm), 1e-9);
        DOUBLES_EQUAL(
            angles[i],
            std::fmod(
                std::atan2(probe[i + 1].y_mm, probe[i + 1].x_mm) * 180 / 3.14159265358979 + 360,
                360),
            1e-6);
    }
}
