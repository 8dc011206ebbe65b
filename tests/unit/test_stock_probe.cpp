// The stock's top by the router's own touch probe (core/modes/stock_top): the lines the box sends
// grbl run on the twin's router with a sheet of known thickness on its bed (its gantry's tilts
// and its probe's scatter included), the [PRB] reports read back, the height against the twin's
// truth; and each refusal with the figure that decided it.
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "board/sim/gcode_runner.hpp"
#include "board/sim/router_twin.hpp"
#include "board/sim/scenes.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/stock_top.hpp"

using namespace calbox;
using geometry::Point2;

namespace {

constexpr double kThicknessMm = 2.35;  // the twin's truth: the sheet the probe touches

sim::StockSheet plywood() {
    sim::StockSheet sheet;
    sheet.corner_mm = {52.3, 61.7};
    sheet.width_mm = 200;
    sheet.depth_mm = 150;
    sheet.angle_deg = 3.2;
    return sheet;
}

sim::RouterTruth seeded_router() {
    auto truth = sim::random_router_truth(3);
    truth.g54_x_mm = -300;
    truth.g54_y_mm = -300;
    truth.g54_z_mm = -62.5;  // the bed's top, machine Z
    return truth;
}

models::TouchProbeSettings probe_settings() {
    models::TouchProbeSettings probe;
    probe.clear_z_mm = -40;
    return probe;
}

// Every line through the twin's grbl as the link sends them: the replies the box reads.
std::vector<std::string> run_on_twin(sim::RouterTwin& twin, const std::vector<std::string>& lines) {
    sim::ToolSettings tool;
    tool.kind = sim::ToolKind::spindle;
    tool.tool_width_mm = 3.175;
    sim::GcodeRunner runner(twin, tool);
    for (const auto& l : lines) runner.run_line(l);
    return runner.result().replies;
}

}  // namespace

TEST_GROUP(StockProbe){};

TEST(StockProbe, the_probed_top_is_the_sheets_thickness_on_the_twin) {
    sim::RouterTwin twin(seeded_router());
    twin.lay_sheet(plywood(), kThicknessMm);
    // 10 mm in and out from the sheet's front-left corner along its diagonal, in machine
    // coordinates (the bed's frame shifted by G54's zero; the router's own errors move the tool a
    // millimetre or two from there, well inside the 10 mm).
    const Point2 corner{52.3 - 300, 61.7 - 300};
    const double d = std::hypot(200.0, 150.0);
    const double turn = 3.2 * 3.14159265358979323846 / 180;
    const double ux = (200 * std::cos(turn) - 150 * std::sin(turn)) / d;
    const double uy = (200 * std::sin(turn) + 150 * std::cos(turn)) / d;
    const modes::StockProbePoints points{{corner.x + 10 * ux, corner.y + 10 * uy},
                                         {corner.x - 10 * ux, corner.y - 10 * uy},
                                         "as given"};
    const auto lines = modes::touch_probe_commands(probe_settings(), points);
    const auto touches = modes::grbl_probe_touches(run_on_twin(twin, lines));
    const auto top = modes::stock_top_from_touches(touches, points, 0.01);
    std::printf("\n  probed top %.4f mm (truth %.2f), touches at machine Z %.4f and %.4f\n",
                top.surface_height_mm, kThicknessMm, top.on_sheet_mm.z, top.beside_mm.z);
    // The gantry's tilts move the tool's height by up to 1.2e-3 mm a mm across X and Y: 0.024 mm
    // over the 20 mm between the touches, and each touch scatters by 0.002 mm.
    DOUBLES_EQUAL(kThicknessMm, top.surface_height_mm, 0.03);
    // grbl reports machine coordinates: the bed's top near G54's Z zero.
    DOUBLES_EQUAL(-62.5, top.beside_mm.z, 0.4);
    DOUBLES_EQUAL(points.on_sheet_mm.x, top.on_sheet_mm.x, 1e-3);
    DOUBLES_EQUAL(points.beside_mm.y, top.beside_mm.y, 1e-3);
    // What is sent: lifted to the clear height before every move over the bed, the probe relative.
    CHECK_EQUAL(13u, lines.size());
    STRCMP_EQUAL("G53 G0 Z-40.000", lines[2].c_str());
    STRCMP_EQUAL("G38.2 Z-25.000 F60.0", lines[5].c_str());
    STRCMP_EQUAL("G53 G0 Z-40.000", lines[7].c_str());
    STRCMP_EQUAL("G53 G0 Z-40.000", lines[12].c_str());
}

TEST(StockProbe, the_points_at_the_found_sheets_corner_lie_either_side_of_it) {
    modes::StockOutline stock;
    const Point2 c[4] = {{-250, -240}, {-50, -240}, {-50, -90}, {-250, -90}};
    const char* names[4] = {"front-left", "front-right", "back-right", "back-left"};
    for (int k = 0; k < 4; ++k) stock.corners[k] = {names[k], c[k], 0.02};
    const auto points = modes::probe_points_at_corner(stock, "stock.json");
    // The nearest corner to the machine's zero is the back-right one: 10 mm towards the middle
    // (-150, -165) and 10 mm away from it.
    const double ux = -100 / std::hypot(100.0, 75.0), uy = -75 / std::hypot(100.0, 75.0);
    DOUBLES_EQUAL(-50 + 10 * ux, points.on_sheet_mm.x, 1e-9);
    DOUBLES_EQUAL(-90 + 10 * uy, points.on_sheet_mm.y, 1e-9);
    DOUBLES_EQUAL(-50 - 10 * ux, points.beside_mm.x, 1e-9);
    DOUBLES_EQUAL(-90 - 10 * uy, points.beside_mm.y, 1e-9);
    CHECK(points.from.find("back-right corner") != std::string::npos);
}

TEST(StockProbe, each_refusal_names_the_figure_that_decided_it) {
    const modes::StockProbePoints points{{-200, -200}, {-220, -220}, "as given"};
    const auto refused = [&](const std::vector<std::string>& replies, const char* says) {
        try {
            modes::stock_top_from_touches(modes::grbl_probe_touches(replies), points, 0.01);
        } catch (const modes::StockError& e) {
            if (std::string(e.what()).find(says) != std::string::npos) return;
            FAIL(e.what());
        }
        FAIL(says);
    };
    refused({"[PRB:-200.000,-200.000,-60.100:1]", "ok", "[PRB:-220.000,-220.000,-62.500:0]"},
            "touched nothing ('[PRB:-220.000,-220.000,-62.500:0]')");
    refused({"[PRB:-200.000,-200.000,-60.100:1]"}, "reported 1 probe touches, not 2");
    refused({"[PRB:-200.000,-200.000,-60.100:1]", "[PRB:-220.000,-219.900,-62.500:1]"},
            "the bed at machine X-220.000 Y-219.900, not at X-220.000 Y-220.000");
    // The points the wrong way round: the sheet's touch below the bed's.
    refused({"[PRB:-200.000,-200.000,-62.500:1]", "[PRB:-220.000,-220.000,-60.100:1]"},
            "the sheet touched at machine Z-62.500, the bed beside it at Z-60.100: a top -2.400 "
            "mm above the bed is no sheet's");
    refused({"[PRB:-200.000,-200.000,nan:1]"}, "is not grbl's");
    // A good pair gives the difference, and its file reads back.
    const auto top = modes::stock_top_from_touches(
        modes::grbl_probe_touches(
            {"[PRB:-200.000,-200.000,-60.100:1]", "ok", "[PRB:-220.000,-220.000,-62.500:1]"}),
        points, 0.01);
    DOUBLES_EQUAL(2.4, top.surface_height_mm, 1e-9);
    DOUBLES_EQUAL(0.01 * std::sqrt(2.0), top.sigma_mm, 1e-12);
    const auto again = modes::stock_top_from_json(modes::stock_top_to_json(top), "stock-top.json");
    DOUBLES_EQUAL(2.4, again.surface_height_mm, 1e-12);
    DOUBLES_EQUAL(-62.5, again.beside_mm.z, 1e-12);
}

TEST(StockProbe, the_twins_grbl_alarms_as_grbl_does) {
    sim::RouterTwin twin(seeded_router());
    twin.lay_sheet(plywood(), kThicknessMm);
    auto probe = probe_settings();
    probe.travel_mm = 5;  // from 22.5 mm above the bed: never reaches it
    const modes::StockProbePoints points{{-200, -200}, {-260, -260}, "as given"};
    try {
        run_on_twin(twin, modes::touch_probe_commands(probe, points));
        FAIL("a probe that touched nothing");
    } catch (const sim::JobMachineError& e) {
        CHECK_EQUAL(5, e.grbl_alarm);
    }
    // Already touching when the cycle starts: alarm 4.
    try {
        run_on_twin(twin, {"G53 G0 X-200 Y-200", "G53 G0 Z-60.5", "G91", "G38.2 Z-5 F60"});
        FAIL("a probe touching before it moved");
    } catch (const sim::JobMachineError& e) {
        CHECK_EQUAL(4, e.grbl_alarm);
    }
}

TEST(StockProbe, the_machine_file_takes_a_touch_probe_on_a_router_on_grbl_only) {
    const auto read = [](const std::string& text) {
        return models::parse_machine_file(text, "machine.toml");
    };
    const std::string router = "[machine]\nkind = \"router\"\nfirmware = \"grbl\"\n[planar]\n";
    const auto m = read(router + "[touch_probe]\nclear_z_mm = -40\nfeed_mm_min = 90\n");
    CHECK(m.touch_probe.has_value());
    DOUBLES_EQUAL(-40, m.touch_probe->clear_z_mm, 0);
    DOUBLES_EQUAL(90, m.touch_probe->feed_mm_min, 0);
    DOUBLES_EQUAL(25, m.touch_probe->travel_mm, 0);
    const auto refused = [&](const std::string& text, const char* says) {
        try {
            read(text);
        } catch (const models::MachineFileError& e) {
            if (std::string(e.what()).find(says) != std::string::npos) return;
            FAIL(e.what());
        }
        FAIL(says);
    };
    refused(router + "[touch_probe]\ntravel_mm = 20\n", "clear_z_mm");
    refused(
        "[machine]\nkind = \"laser\"\nfirmware = \"grbl\"\n[planar]\n[touch_probe]\n"
        "clear_z_mm = -40\n",
        "[touch_probe] is a router's on grbl (G38.2), not a laser's on grbl");
}
