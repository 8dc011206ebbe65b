// The stock on the bed seen by the box's camera (a sheet found and its outline placed) and a
// print-and-cut card's printed lines cut where they lie, each against the twin's truth.
#include "tests/unit/bed_view_rig.hpp"

TEST_GROUP(StockTwin){};

namespace {

// The sheet photographed on the router's bed at its top's height, found by the box, and each
// corner judged against the machine coordinates a job through the correction must aim at to
// land on the twin's corner.
struct StockVerdict {
    modes::StockOutline found;
    double worst_corner_mm = 0, rotation_error_deg = 0;
};

StockVerdict find_sheet(const sim::StockSheet& sheet, const sim::PhotoSettings& photo,
                        double top_mm) {
    const auto& router = calibrated_router();
    const auto picture = sim::render_photo(router.bench.camera, router.pose_over(top_mm),
                                           sim::SheetScene(sheet, 4), photo);
    StockVerdict v;
    v.found = modes::find_stock(router.camera, router.plane, test::view_of(picture),
                                router.solution, top_mm, "result.json");
    const auto truth = sim::SheetScene(sheet, 4).corners();
    std::array<Point2, 4> aims;
    for (int k = 0; k < 4; ++k) {
        aims[k] = router.aim_for(truth[k]);
        const Point2 got = v.found.corners[k].machine_mm;
        v.worst_corner_mm =
            std::max(v.worst_corner_mm, std::hypot(got.x - aims[k].x, got.y - aims[k].y));
    }
    const double true_rotation =
        std::atan2(aims[1].y - aims[0].y, aims[1].x - aims[0].x) * 180 / kPi;
    v.rotation_error_deg = std::abs(v.found.rotation_deg - true_rotation);
    UT_PRINT(("stock " + std::to_string(sheet.width_mm) + " x " + std::to_string(sheet.depth_mm) +
              " turned " + std::to_string(sheet.angle_deg) + " deg: corners within " +
              std::to_string(v.worst_corner_mm) + " mm (sigma stated " +
              std::to_string(v.found.corners[0].sigma_mm) + "), rotation " +
              std::to_string(v.found.rotation_deg) + " deg, off by " +
              std::to_string(v.rotation_error_deg) + "; edge points " +
              std::to_string(v.found.edge_points[0]) + "/" +
              std::to_string(v.found.edge_points[1]) + "/" +
              std::to_string(v.found.edge_points[2]) + "/" +
              std::to_string(v.found.edge_points[3]) + ", set aside " +
              std::to_string(v.found.edge_points_set_aside) + ", under glare " +
              std::to_string(v.found.edge_points_under_glare))
                 .c_str());
    return v;
}

}  // namespace

// The bars: the corner within 0.1 mm, the rotation within 0.05 degrees.
TEST(StockTwin, a_light_sheet_turned_on_the_spoilboard_is_found_to_its_corners) {
    sim::StockSheet sheet;
    sheet.corner_mm = {52.3, 61.7};
    sheet.width_mm = 220, sheet.depth_mm = 160, sheet.angle_deg = 3.2;
    sheet.sheet_albedo = 0.75, sheet.bed_albedo = 0.3;
    const auto v = find_sheet(sheet, calibrated_router().bench.photo, 1.5);
    CHECK(v.found.lighter_than_bed);
    STRCMP_EQUAL("front-left", v.found.corners[0].name.c_str());
    CHECK(v.worst_corner_mm < 0.1);
    CHECK(v.rotation_error_deg < 0.05);
    DOUBLES_EQUAL(220, v.found.width_mm, 0.2);
    DOUBLES_EQUAL(160, v.found.depth_mm, 0.2);
    CHECK_EQUAL(0, v.found.edge_points_set_aside);
}

TEST(StockTwin, a_dark_sheet_turned_the_other_way_is_found_too) {
    sim::StockSheet sheet;
    sheet.corner_mm = {120.4, 30.2};
    sheet.width_mm = 140, sheet.depth_mm = 200, sheet.angle_deg = -7.5;
    sheet.sheet_albedo = 0.07, sheet.bed_albedo = 0.55;
    const auto v = find_sheet(sheet, calibrated_router().bench.photo, 3);
    CHECK(!v.found.lighter_than_bed);
    CHECK(v.worst_corner_mm < 0.1);
    CHECK(v.rotation_error_deg < 0.05);
}

// The box's lamp mirrored by a glossy sheet: a washed-out lobe over part of it.
TEST(StockTwin, the_lamps_glare_over_part_of_the_sheet_leaves_its_corners) {
    sim::StockSheet sheet;
    sheet.corner_mm = {40.8, 70.1};
    sheet.width_mm = 230, sheet.depth_mm = 150, sheet.angle_deg = 1.4;
    sheet.sheet_albedo = 0.6, sheet.bed_albedo = 0.25;
    auto photo = calibrated_router().bench.photo;
    photo.glare = sim::glare_of_surface("laminated");
    const auto v = find_sheet(sheet, photo, 1.5);
    // Where the sensor clipped the edge it is left out (about half the front and right edges
    // here), and what is left still tells the corners.
    CHECK(v.found.edge_points_under_glare > 100);
    CHECK(v.worst_corner_mm < 0.1);
    CHECK(v.rotation_error_deg < 0.05);
}

// A sheet hanging over the bed's edge, out of the camera's sight: its outline cannot be told, and
// no corner is made up.
TEST(StockTwin, a_sheet_running_out_of_sight_is_refused) {
    sim::StockSheet sheet;
    sheet.corner_mm = {-80, 60};
    sheet.width_mm = 200, sheet.depth_mm = 150, sheet.angle_deg = 2;
    const auto& router = calibrated_router();
    const auto picture = sim::render_photo(router.bench.camera, router.pose_over(1.5),
                                           sim::SheetScene(sheet, 4), router.bench.photo);
    try {
        modes::find_stock(router.camera, router.plane, test::view_of(picture), router.solution, 1.5,
                          "result.json");
        FAIL("a sheet out of sight was found");
    } catch (const modes::StockError& e) {
        STRCMP_CONTAINS("no sheet with four straight edges in X 0.0..300.0 Y 0.0..300.0 mm",
                        e.what());
    }
}

// Corners by name, or the one nearest the machine's zero (grbl's: the back right).
TEST(StockTwin, a_corner_is_chosen_by_name_or_as_the_one_nearest_the_machines_zero) {
    modes::StockOutline stock;
    const char* names[4] = {"front-left", "front-right", "back-right", "back-left"};
    const Point2 at[4] = {{-250, -240}, {-30, -230}, {-40, -70}, {-260, -80}};
    for (int k = 0; k < 4; ++k) stock.corners[k] = {names[k], at[k], 0.01};
    STRCMP_EQUAL("back-right", modes::stock_corner(stock, "nearest").name.c_str());
    DOUBLES_EQUAL(-260, modes::stock_corner(stock, "back-left").machine_mm.x, 0);
    CHECK_THROWS(modes::StockError, modes::stock_corner(stock, "left"));
}

// The job placed by the sheet's corner (calbox compensate --work-zero camera): a drilling job
// written around the sheet's front-left corner, 10 mm in from its edges, compensated through the
// result with the corner and the turn the box found; each hole drilled by the twin lands where
// the job meant it on the real sheet, within the 0.1 mm.
TEST(StockTwin, a_job_placed_at_the_found_corner_lands_on_the_sheet_where_it_was_meant) {
    sim::StockSheet sheet;
    sheet.corner_mm = {52.3, 61.7};
    sheet.width_mm = 220, sheet.depth_mm = 160, sheet.angle_deg = 3.2;
    sheet.sheet_albedo = 0.75, sheet.bed_albedo = 0.3;
    const auto& router = calibrated_router();
    const auto v = find_sheet(sheet, router.bench.photo, 1.5);
    const Point2 meant[5] = {{10, 10}, {210, 10}, {210, 150}, {10, 150}, {110, 80}};
    std::string job = "G21 G90 G54\n";
    for (const auto& p : meant)
        job += "G0 X" + std::to_string(p.x) + " Y" + std::to_string(p.y) + "\nG1 Z-2 F300\nG0 Z5\n";
    modes::JobRequest request;
    request.result_text = modes::planar_result_to_json(
        router.solution, modes::planar_firmware_settings(router.machine, router.solution));
    request.result_name = "result.json";
    request.job_text = job;
    request.job_name = "holes.nc";
    request.work_zero = "camera";
    request.stock_text = modes::stock_to_json(v.found, router.solution.machine_fingerprint);
    request.stock_name = "stock.json";
    request.stock_corner = "front-left";
    request.date = "2026-11-29";
    const auto done = modes::compensate_job(request);
    STRCMP_CONTAINS("the camera: stock.json's front-left corner at machine X",
                    done.frame_line.c_str());
    // The controller's G54 zero is the found corner; each rapid's X Y is commanded from there.
    const Point2 zero = v.found.corners[0].machine_mm;
    const double a = sheet.angle_deg * kPi / 180;
    // Where each plunge is: the last X Y written before it.
    std::vector<Point2> written;
    Point2 at;
    std::istringstream lines(done.text);
    for (std::string line; std::getline(lines, line);) {
        if (line.rfind("G0 X", 0) == 0)
            CHECK_EQUAL(2, std::sscanf(line.c_str(), "G0 X%lf Y%lf", &at.x, &at.y));
        if (line.rfind("G1 Z-2", 0) == 0) written.push_back(at);
    }
    CHECK_EQUAL(5u, written.size());
    double worst = 0;
    for (std::size_t k = 0; k < written.size() && k < 5; ++k) {
        const Point2 command{written[k].x + zero.x, written[k].y + zero.y};
        const sim::Vec3 tool = sim::router_tool_position_mm(
            router.truth, {command.x, command.y, -router.machine.cut_depth_mm}, {true, true});
        const sim::Vec2 on_sheet{
            sheet.corner_mm.x + meant[k].x * std::cos(a) - meant[k].y * std::sin(a),
            sheet.corner_mm.y + meant[k].x * std::sin(a) + meant[k].y * std::cos(a)};
        worst = std::max(worst, std::hypot(tool.x - on_sheet.x, tool.y - on_sheet.y));
    }
    UT_PRINT(("a job placed at the found corner: its holes within " + std::to_string(worst) +
              " mm of where it meant them on the sheet")
                 .c_str());
    CHECK(worst < 0.1);
    // Offsets of its own would move the turn's centre: refused, naming the line.
    request.job_text = "G21 G90\nG10 L2 P1 X5 Y5\nG0 X1 Y1\n";
    try {
        modes::compensate_job(request);
        FAIL("a turned job setting its own offset was compensated");
    } catch (const modes::JobError& e) {
        STRCMP_CONTAINS("line 2: G10 L2 with X or Y in a job placed turned with the stock",
                        e.what());
    }
}

TEST_GROUP(PrintAndCutTwin){};

namespace {

// A card printed with a drawing and its marks (filled 5 mm circles), lying on the router's bed
// turned and shifted, the printer's stretch on it: where a drawing's point really is.
struct PrintedCard {
    sim::Vec2 origin_mm;
    double angle_deg = 0, stretch = 1;
    sim::Vec2 at(Point2 d) const {
        const double a = angle_deg * kPi / 180;
        return {origin_mm.x + stretch * (std::cos(a) * d.x - std::sin(a) * d.y),
                origin_mm.y + stretch * (std::sin(a) * d.x + std::cos(a) * d.y)};
    }
};

// The drawing's cut line: a five-lobed outline around (80, 60), closed.
std::vector<Point2> cut_line() {
    std::vector<Point2> points;
    for (int k = 0; k <= 120; ++k) {
        const double t = 2 * kPi * k / 120, r = 40 + 8 * std::cos(5 * t);
        points.push_back({80 + r * std::cos(t), 60 + r * std::sin(t)});
    }
    return points;
}

// The cut line as the card shows it: its strokes (0.4 mm of ink) added to `ink`, and its points.
std::vector<sim::Vec2> printed_line(const PrintedCard& card, const std::vector<Point2>& line,
                                    std::vector<sim::StrokeSegment>& ink) {
    std::vector<sim::Vec2> printed;
    for (const auto& p : line) printed.push_back(card.at(p));
    for (std::size_t k = 0; k + 1 < printed.size(); ++k)
        ink.push_back(
            {{printed[k].x, printed[k].y, 0}, {printed[k + 1].x, printed[k + 1].y, 0}, 0.4});
    return printed;
}

struct CutVerdict {
    modes::Registration registration;
    double mean_mm = 0, worst_mm = 0;
    std::size_t points = 0;
};

// Prints the card, photographs it at its top (0.3 mm), finds the marks, compensates the cut job
// (in the drawing's frame) through --register and runs it on the twin router: each point the
// tool really cut against the printed line.
// Crosses (`kind`) span 10 mm tip to tip with 0.5 mm bars; circles are 5 mm across.
CutVerdict print_and_cut(const PrintedCard& card, const std::vector<Point2>& marks,
                         const sim::PhotoSettings& photo,
                         modes::MarkKind kind = modes::MarkKind::circles) {
    const auto& router = calibrated_router();
    constexpr double kTopMm = 0.3, kCrossMm = 10, kBarMm = 0.5;
    std::vector<sim::StrokeSegment> ink;
    for (const auto& m : marks) {
        if (kind == modes::MarkKind::crosses) {
            // Each bar a stroke with round ends: its ends half a bar in from the tips.
            const double reach = (kCrossMm - kBarMm) / 2;
            for (const Point2 along : {Point2{reach, 0}, Point2{0, reach}}) {
                const sim::Vec2 a = card.at({m.x - along.x, m.y - along.y});
                const sim::Vec2 b = card.at({m.x + along.x, m.y + along.y});
                ink.push_back({{a.x, a.y, 0}, {b.x, b.y, 0}, kBarMm * card.stretch});
            }
            continue;
        }
        const sim::Vec2 c = card.at(m);
        ink.push_back({{c.x, c.y, 0}, {c.x, c.y, 0}, 5.0 * card.stretch});
    }
    const auto line = cut_line();
    const auto printed = printed_line(card, line, ink);
    const auto pose = router.pose_over(kTopMm);
    const auto picture = sim::render_photo(
        router.bench.camera, pose,
        sim::StrokeScene(std::move(ink), 0.85, 0.08, 4,
                         sim::stroke_footprint_mm(router.bench.camera, pose.translation_mm.norm())),
        photo);
    modes::RegistrationRequest request;
    request.marks_drawing_mm = marks;
    request.kind = kind;
    request.mark_diameter_mm = kind == modes::MarkKind::crosses ? kCrossMm : 5;
    request.cross_line_mm = kBarMm;
    request.surface_height_mm = kTopMm;
    CutVerdict v;
    v.registration = modes::register_marks(router.camera, router.plane, test::view_of(picture),
                                           router.solution, request, "result.json");
    // The cut: the drawing's line in its own frame, as a laser or a drag knife follows it.
    std::string job = "G21 G90 G54\nM3 S12000\nG0 Z5\nG0 X" + std::to_string(line[0].x) + " Y" +
                      std::to_string(line[0].y) + "\nG1 Z-0.2 F300\n";
    for (const auto& p : line)
        job += "G1 X" + std::to_string(p.x) + " Y" + std::to_string(p.y) + " F600\n";
    job += "G0 Z5\n";
    modes::JobRequest cut;
    cut.result_text = modes::planar_result_to_json(
        router.solution, modes::planar_firmware_settings(router.machine, router.solution));
    cut.result_name = "result.json";
    cut.job_text = job;
    cut.job_name = "cut.nc";
    cut.registration_text =
        modes::registration_to_json(v.registration, router.solution.machine_fingerprint);
    cut.registration_name = "marks.json";
    cut.date = "2026-11-29";
    const auto done = modes::compensate_job(cut);
    // The controller's G54 is the drawing's zero the marks gave; the twin runs in the frame the
    // router was calibrated in (its work zero), so each written X Y moves by that zero.
    const Point2 zero = v.registration.origin_mm;
    std::string in_twin;
    std::istringstream lines(done.text);
    for (std::string l; std::getline(lines, l);) {
        const auto x = l.find(" X"), y = l.find(" Y");
        if (l.empty() || l[0] == ';' || x == std::string::npos || y == std::string::npos) {
            in_twin += l + "\n";
            continue;
        }
        const double xv = std::stod(l.substr(x + 2)), yv = std::stod(l.substr(y + 2));
        const auto rest = l.find(' ', y + 2);
        in_twin += l.substr(0, x) + " X" + std::to_string(xv + zero.x) + " Y" +
                   std::to_string(yv + zero.y) + (rest == std::string::npos ? "" : l.substr(rest)) +
                   "\n";
    }
    sim::RouterTwin twin(router.truth);
    sim::ToolSettings tool;
    tool.kind = sim::ToolKind::spindle;
    tool.tool_width_mm = 0.2;
    sim::GcodeRunner runner(twin, tool);
    std::istringstream run(in_twin);
    runner.run(run);
    double sum = 0;
    for (const auto& s : runner.result().strokes)
        for (const sim::Vec3& p : {s.a_mm, s.b_mm}) {
            if (p.z > -0.1) continue;  // not cutting
            const double d = sim::distance_to_polyline({p.x, p.y}, printed);
            sum += d;
            v.worst_mm = std::max(v.worst_mm, d);
            ++v.points;
        }
    v.mean_mm = sum / static_cast<double>(std::max<std::size_t>(1, v.points));
    UT_PRINT(("print and cut, " + std::to_string(marks.size()) + " marks: turned " +
              std::to_string(v.registration.rotation_deg) + " deg, scale " +
              std::to_string(v.registration.scale) + ", worst mark " +
              std::to_string(v.registration.worst_residual_mm) +
              " mm; the cut from the printed "
              "line " +
              std::to_string(v.mean_mm) + " mm mean, " + std::to_string(v.worst_mm) +
              " worst over " + std::to_string(v.points) + " points")
                 .c_str());
    return v;
}

const std::vector<Point2> kFourMarks = {{0, 0}, {160, 0}, {160, 125}, {0, 110}};

}  // namespace

// Four marks: the turn, the shift and the printer's 0.3 % stretch fitted; the cut on the printed
// line within the issue's 0.1 mm everywhere.
TEST(PrintAndCutTwin, four_marks_place_a_stretched_drawing_and_the_cut_follows_the_print) {
    const PrintedCard card{{63.4, 71.9}, -4.3, 1.003};
    const auto v = print_and_cut(card, kFourMarks, calibrated_router().bench.photo);
    CHECK(v.registration.scale_fitted);
    DOUBLES_EQUAL(1.003, v.registration.scale, 3e-4);
    CHECK(v.points > 200);
    CHECK(v.worst_mm < 0.1);
    CHECK(v.mean_mm < 0.05);
}

// Three marks hold the scale at 1; the lamp's glare over part of the card.
TEST(PrintAndCutTwin, three_marks_under_the_lamps_glare_place_the_drawing_too) {
    const PrintedCard card{{82.0, 65.5}, 6.1, 1.0};
    auto photo = calibrated_router().bench.photo;
    photo.glare = sim::glare_of_surface("pei");
    const auto v = print_and_cut(card, {{0, 0}, {160, 0}, {0, 110}}, photo);
    CHECK(!v.registration.scale_fitted);
    CHECK(v.worst_mm < 0.1);
    CHECK(v.mean_mm < 0.05);
}

// The third kind: four crosses (10 mm, 0.5 mm bars) on a stretched card under the PEI lamp's
// glare; the cut within the 0.1 mm of the printed line.
TEST(PrintAndCutTwin, four_printed_crosses_place_a_stretched_drawing) {
    const PrintedCard card{{71.6, 58.3}, -2.7, 1.002};
    auto photo = calibrated_router().bench.photo;
    photo.glare = sim::glare_of_surface("pei");
    const auto v = print_and_cut(card, kFourMarks, photo, modes::MarkKind::crosses);
    CHECK(v.registration.scale_fitted);
    DOUBLES_EQUAL(1.002, v.registration.scale, 3e-4);
    CHECK(v.registration.worst_residual_mm < 0.05);
    CHECK(v.points > 200);
    CHECK(v.worst_mm < 0.1);
    CHECK(v.mean_mm < 0.05);
}

// Marks at a rectangle's corners fit the drawing turned half round as well as the right way:
// nothing tells which, and the box says so.
TEST(PrintAndCutTwin, marks_laid_symmetrically_are_refused) {
    const PrintedCard card{{63.4, 71.9}, 2, 1.0};
    try {
        print_and_cut(card, {{0, 0}, {160, 0}, {160, 120}, {0, 120}},
                      calibrated_router().bench.photo);
        FAIL("a symmetric layout was placed");
    } catch (const modes::RegistrationError& e) {
        STRCMP_CONTAINS("the marks lie symmetrically: the drawing fits them turned 180 degrees",
                        e.what());
    }
}

// The second kind: ArUco markers printed at the drawing's corners, each told by its id (no
// layout is ambiguous, even a rectangle's). The twin prints them square to the bed (its sticker
// scene), which moves no marker's centre.
TEST(PrintAndCutTwin, aruco_markers_told_by_their_ids_place_the_drawing) {
    const auto& router = calibrated_router();
    const PrintedCard card{{70.2, 66.8}, 3.4, 1.002};
    const std::vector<Point2> marks = {{0, 0}, {160, 0}, {160, 120}, {0, 120}};
    const std::vector<int> ids = {3, 7, 11, 15};
    constexpr double kTopMm = 0.3, kSideMm = 10;
    std::vector<sim::StrokeSegment> ink;
    const auto line = cut_line();
    const auto printed = printed_line(card, line, ink);
    const auto pose = router.pose_over(kTopMm);
    const sim::StrokeScene drawing(
        std::move(ink), 0.85, 0.08, 4,
        sim::stroke_footprint_mm(router.bench.camera, pose.translation_mm.norm()));
    std::vector<sim::ReferenceMark> printed_marks;
    for (std::size_t i = 0; i < marks.size(); ++i)
        printed_marks.push_back({ids[i], card.at(marks[i])});
    const double identity[2][2] = {{1, 0}, {0, 1}};
    const sim::ReferenceMarksScene scene(drawing, printed_marks, "DICT_4X4_50",
                                         kSideMm * card.stretch, 4, identity, {0, 0});
    const auto picture = sim::render_photo(router.bench.camera, pose, scene, router.bench.photo);
    modes::RegistrationRequest request;
    request.kind = modes::MarkKind::markers;
    request.marks_drawing_mm = marks;
    request.marker_ids = ids;
    request.mark_diameter_mm = kSideMm;
    request.surface_height_mm = kTopMm;
    const auto found = modes::register_marks(router.camera, router.plane, test::view_of(picture),
                                             router.solution, request, "result.json");
    // Where the fitted place puts each drawing point, judged where the corrected tool lands.
    double worst = 0;
    for (const auto& d : line) {
        const double a = found.rotation_deg * kPi / 180;
        const Point2 machine{
            found.origin_mm.x + found.scale * (std::cos(a) * d.x - std::sin(a) * d.y),
            found.origin_mm.y + found.scale * (std::sin(a) * d.x + std::cos(a) * d.y)};
        const sim::Vec2 tool = router.lands(machine);
        const sim::Vec2 meant = card.at(d);
        worst = std::max(worst, std::hypot(tool.x - meant.x, tool.y - meant.y));
    }
    UT_PRINT(("print and cut, ArUco markers: scale " + std::to_string(found.scale) +
              ", worst mark " + std::to_string(found.worst_residual_mm) +
              " mm; the line's points within " + std::to_string(worst) +
              " mm where the corrected tool lands")
                 .c_str());
    DOUBLES_EQUAL(1.002, found.scale, 3e-4);
    CHECK(worst < 0.1);
    // A marker not printed is named.
    request.marker_ids[2] = 40;
    try {
        modes::register_marks(router.camera, router.plane, test::view_of(picture), router.solution,
                              request, "result.json");
        FAIL("a missing marker was placed");
    } catch (const modes::RegistrationError& e) {
        STRCMP_CONTAINS("marker 40 (DICT_4X4_50, drawing X160.00 Y120.00) is not in the photo",
                        e.what());
    }
}
