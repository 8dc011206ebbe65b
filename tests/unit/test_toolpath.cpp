// Fills of the seed simulator's four drawings, judged against an independent rasteriser
// (cv::fillPoly of the polygon read straight from the file), and printed by the twin.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "board/sim/camera_reference.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenes.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_file.hpp"
#include "tests/support/test_data.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;

namespace {

const char* kLaser = R"toml(
[machine]
kind = "laser"
firmware = "grbl"
bed_size_x_mm = 200.0
bed_size_y_mm = 200.0
tool_width_mm = 0.1
)toml";

std::string drawing(const std::string& name) {
    return test::read_test_data("svg/" + name + ".svg");
}

// The outline as the test reads it: the polygon's points, fitted to 40 mm and centred as the
// job promises (larger side 40 mm, y flipped, centred on the bed).
std::vector<cv::Point2d> outline_of(const std::string& svg, cv::Point2d bed_centre) {
    const auto start = svg.find("points=\"");
    if (start == std::string::npos) FAIL("no points in the drawing");
    std::string points = svg.substr(start + 8, svg.find('"', start + 8) - start - 8);
    std::replace(points.begin(), points.end(), ',', ' ');
    std::stringstream in(points);
    std::vector<cv::Point2d> p;
    double x, y;
    while (in >> x >> y) p.emplace_back(x, y);
    double xmin = 1e9, xmax = -1e9, ymin = 1e9, ymax = -1e9;
    for (const auto& q : p)
        xmin = std::min(xmin, q.x), xmax = std::max(xmax, q.x), ymin = std::min(ymin, q.y),
        ymax = std::max(ymax, q.y);
    const double s = 40.0 / std::max(xmax - xmin, ymax - ymin);
    for (auto& q : p)
        q = {bed_centre.x + (q.x - (xmin + xmax) / 2) * s,
             bed_centre.y - (q.y - (ymin + ymax) / 2) * s};
    return p;
}

struct FillFigures {
    double iou = 0;
    double travel_fraction = 0;
    double worst_spacing_error = 0;
    bool infill_inside = true;
    int infill_lines = 0;
};

FillFigures judge(const std::string& name, const char* machine_text, double spacing) {
    const auto machine = models::parse_machine_file(machine_text, "test machine");
    jobs::SvgJobSettings settings;
    settings.fit_mm = 40;
    settings.spacing_mm = spacing;
    const auto job = jobs::plan_svg_job(drawings::parse_svg(drawing(name)), machine, settings);
    const cv::Point2d centre = machine.is_delta() ? cv::Point2d(0, 0) : cv::Point2d(100, 100);
    const auto outline = outline_of(drawing(name), centre);
    const std::vector<cv::Point2f> outline_f(outline.begin(), outline.end());
    // Both rasters at 0.01 mm, 4 bits of sub-pixel position.
    constexpr double kPxPerMm = 100;
    constexpr int kShift = 4;
    const cv::Point2d origin = centre - cv::Point2d(22, 22);
    const auto to_px = [&](double x, double y) {
        return cv::Point(static_cast<int>(std::lround((x - origin.x) * kPxPerMm * (1 << kShift))),
                         static_cast<int>(std::lround((y - origin.y) * kPxPerMm * (1 << kShift))));
    };
    cv::Mat truth = cv::Mat::zeros(4400, 4400, CV_8U), made = truth.clone();
    std::vector<cv::Point> polygon;
    for (const auto& p : outline) polygon.push_back(to_px(p.x, p.y));
    cv::fillPoly(truth, std::vector<std::vector<cv::Point>>{polygon}, 255, cv::LINE_8, kShift);
    const int width_px = static_cast<int>(std::lround(job.line_width_mm * kPxPerMm));
    FillFigures f;
    std::map<long, int> offsets;  // infill lines by their offset across the scan direction
    cv::Point2d direction;
    double longest = 0;
    for (const auto& move : job.toolpath.moves) {
        if (move.kind == jobs::MoveKind::infill && move.length_mm() > longest) {
            longest = move.length_mm();
            direction =
                cv::Point2d(move.to.x - move.from.x, move.to.y - move.from.y) / move.length_mm();
        }
    }
    for (const auto& move : job.toolpath.moves) {
        if (move.kind == jobs::MoveKind::travel) continue;
        cv::line(made, to_px(move.from.x, move.from.y), to_px(move.to.x, move.to.y), 255, width_px,
                 cv::LINE_8, kShift);
        if (move.kind != jobs::MoveKind::infill) continue;
        for (double t = 0; t <= 1.0; t += 0.05 / std::max(0.05, move.length_mm())) {
            const cv::Point2d p(move.from.x + t * (move.to.x - move.from.x),
                                move.from.y + t * (move.to.y - move.from.y));
            if (cv::pointPolygonTest(outline_f, cv::Point2f(p), false) < 0) f.infill_inside = false;
        }
        const cv::Point2d d(move.to.x - move.from.x, move.to.y - move.from.y);
        if (move.length_mm() > 3 * spacing &&
            std::abs(d.x * direction.y - d.y * direction.x) < 1e-6 * move.length_mm()) {
            const double across = -move.from.x * direction.y + move.from.y * direction.x;
            offsets[std::lround(across * 1e5)]++;
            ++f.infill_lines;
        }
    }
    // Neighbouring lines lie one spacing apart (or whole spacings, across a gap).
    long previous = 0;
    bool first = true;
    for (const auto& [offset, count] : offsets) {
        if (!first) {
            const double gap = (offset - previous) / 1e5;
            const double steps = std::round(gap / spacing);
            f.worst_spacing_error =
                std::max(f.worst_spacing_error, std::abs(gap - steps * spacing) / spacing);
        }
        previous = offset;
        first = false;
    }
    const double both = cv::countNonZero(truth & made), either = cv::countNonZero(truth | made);
    f.iou = both / either;
    f.travel_fraction = job.toolpath.travel_length_mm() / job.toolpath.working_length_mm();
    return f;
}

void check_fill(const std::string& name, const char* machine, double spacing, double min_iou) {
    const auto f = judge(name, machine, spacing);
    const std::string what = name + (machine == kLaser ? " laser" : " printer");
    UT_PRINT((what + ": IoU " + std::to_string(f.iou) + ", travel " +
              std::to_string(100 * f.travel_fraction) + " %, worst spacing error " +
              std::to_string(100 * f.worst_spacing_error) + " %")
                 .c_str());
    CHECK_TEXT(f.iou >= min_iou, (what + " IoU " + std::to_string(f.iou)).c_str());
    CHECK_TEXT(f.infill_inside, (what + ": an infill line leaves the outline").c_str());
    CHECK_TEXT(f.infill_lines > 10, (what + ": too few infill lines to judge").c_str());
    CHECK_TEXT(f.worst_spacing_error <= 0.01,
               (what + " spacing error " + std::to_string(f.worst_spacing_error)).c_str());
    CHECK_TEXT(f.travel_fraction <= 0.05,
               (what + " travel " + std::to_string(f.travel_fraction)).c_str());
}

}  // namespace

TEST_GROUP(SeedDrawings){};

TEST(SeedDrawings, avion_fills_its_outline) {
    check_fill("avion", kLaser, 0.1, 0.99);
    check_fill("avion", test::kDeltaMachineToml, 0.45, 0.98);
}
TEST(SeedDrawings, casa_fills_its_outline) {
    check_fill("casa", kLaser, 0.1, 0.99);
    check_fill("casa", test::kDeltaMachineToml, 0.45, 0.98);
}
TEST(SeedDrawings, forma1_fills_its_outline) {
    check_fill("forma1", kLaser, 0.1, 0.99);
    check_fill("forma1", test::kDeltaMachineToml, 0.45, 0.98);
}
TEST(SeedDrawings, forma2_fills_its_outline) {
    check_fill("forma2", kLaser, 0.1, 0.99);
    check_fill("forma2", test::kDeltaMachineToml, 0.45, 0.98);
}

TEST(SeedDrawings, printer_spacing_below_the_line_width_is_refused_with_the_range) {
    const auto machine = models::parse_machine_file(test::kDeltaMachineToml, "test machine");
    try {
        jobs::checked_spacing_mm(machine, 0.3);
        FAIL("accepted 0.3 mm spacing with a 0.45 mm line");
    } catch (const jobs::JobError& e) {
        STRCMP_CONTAINS("valid range 0.45 to 4.5 mm", e.what());
    }
}

TEST_GROUP(TwinPrintsDrawing){};

TEST(TwinPrintsDrawing, photo_of_the_printed_house_shows_its_area_within_one_percent) {
    const auto machine = models::parse_machine_file(test::kDeltaMachineToml, "test machine");
    jobs::SvgJobSettings settings;
    settings.fit_mm = 40;
    const auto job = jobs::plan_svg_job(drawings::parse_svg(drawing("casa")), machine, settings);
    const std::string gcode = jobs::write_gcode(job, machine, "casa");
    sim::DeltaParams exact;
    sim::DeltaTwin twin(exact, exact);
    auto strokes = test::print_on_twin(twin, gcode);
    sim::CameraIntrinsics camera;
    camera.width_px = 1000;
    camera.height_px = 900;
    camera.fx = camera.fy = 5700;  // 0.07 mm/px at 400 mm
    camera.cx = 499.5;
    camera.cy = 449.5;
    const sim::Pose pose = sim::look_at_pose({0, -35, 400}, {0, 0, 0}, 0);
    sim::PhotoSettings photo;
    photo.blur_sigma_px = 0.7;
    photo.noise_sigma_dn = 2.0;
    const auto image = test::photo_of_print(camera, pose, std::move(strokes), photo);
    // Area in the photo: each pixel's share of material times its footprint on the bed.
    const double bed_dn = 0.08 * 240, material_dn = 0.85 * 240;
    const auto bed_point = [&](double u, double v) {
        const auto n = sim::undistort_pixel(camera, u, v);
        const sim::Vec3 d = pose.rotation.transposed() * sim::Vec3{n.x, n.y, 1};
        const sim::Vec3 o = pose.camera_centre_in_plane();
        const double s = (0.2 - o.z) / d.z;
        return sim::Vec2{o.x + s * d.x, o.y + s * d.y};
    };
    double area = 0;
    for (int v = 0; v < camera.height_px; ++v) {
        for (int u = 0; u < camera.width_px; ++u) {
            const double share =
                (image.pixels[static_cast<std::size_t>(v) * camera.width_px + u] - bed_dn) /
                (material_dn - bed_dn);
            if (share <= 0.02) continue;  // bed and its noise
            const auto c = bed_point(u, v), r = bed_point(u + 1, v), d = bed_point(u, v + 1);
            area += share * std::abs((r.x - c.x) * (d.y - c.y) - (r.y - c.y) * (d.x - c.x));
        }
    }
    const auto outline = outline_of(drawing("casa"), {0, 0});
    std::vector<cv::Point2f> outline_f(outline.begin(), outline.end());
    const double truth = std::abs(cv::contourArea(outline_f));
    UT_PRINT(("printed house: photo area " + std::to_string(area) + " mm^2, drawing " +
              std::to_string(truth) + " mm^2")
                 .c_str());
    CHECK_TEXT(std::abs(area - truth) / truth < 0.01,
               ("photo area " + std::to_string(area) + " mm^2 against the drawing's " +
                std::to_string(truth))
                   .c_str());
}
