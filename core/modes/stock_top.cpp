#include "core/modes/stock_top.hpp"

#include <cmath>
#include <cstdio>

#include "core/modes/json_file.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {

using geometry::Point2;
using geometry::Point3;

namespace {

constexpr const char* kStockTopSchema = "calbox.stock-top/1";
constexpr double kMostTopMm = 200;
// grbl reports to 0.001 mm: a touch further than this from where it was sent in X or Y is not
// this cycle's (a report left from an earlier one, or a move that went elsewhere).
constexpr double kTouchPlaceToleranceMm = 0.01;

}  // namespace

StockProbePoints probe_points_at_corner(const StockOutline& stock, const std::string& source,
                                        double inset_mm) {
    const auto& corner = stock_corner(stock, "nearest");
    Point2 middle{};
    for (const auto& c : stock.corners) {
        middle.x += c.machine_mm.x / 4;
        middle.y += c.machine_mm.y / 4;
    }
    const double dx = middle.x - corner.machine_mm.x, dy = middle.y - corner.machine_mm.y;
    const double length = std::hypot(dx, dy);
    if (!(length > 2 * inset_mm))
        throw StockError(source + ": the sheet's diagonal (" + number_text("%.1f", 2 * length) +
                         " mm) is too short to probe " + number_text("%.0f", inset_mm) +
                         " mm in from its corner");
    const double ux = dx / length, uy = dy / length;
    return {{corner.machine_mm.x + inset_mm * ux, corner.machine_mm.y + inset_mm * uy},
            {corner.machine_mm.x - inset_mm * ux, corner.machine_mm.y - inset_mm * uy},
            source + "'s " + corner.name + " corner, " + number_text("%.0f", inset_mm) +
                " mm in and out along its diagonal"};
}

std::vector<std::string> touch_probe_commands(const models::TouchProbeSettings& probe,
                                              const StockProbePoints& points) {
    const std::string lift = "G53 G0 Z" + number_text("%.3f", probe.clear_z_mm);
    const std::string down = "G38.2 Z-" + number_text("%.3f", probe.travel_mm) + " F" +
                             number_text("%.1f", probe.feed_mm_min);
    std::vector<std::string> lines{"G21", "G90", lift};
    for (const Point2 at : {points.on_sheet_mm, points.beside_mm})
        lines.insert(lines.end(), {"G53 G0 " + machine_xy_text(at), "G91", down, "G90", lift});
    return lines;
}

std::vector<Point3> grbl_probe_touches(const std::vector<std::string>& replies) {
    std::vector<Point3> touches;
    for (const auto& reply : replies) {
        if (reply.rfind("[PRB:", 0) != 0) continue;
        Point3 p;
        int touched = -1;
        char close = 0;
        if (std::sscanf(reply.c_str() + 5, "%lf,%lf,%lf:%d%c", &p.x, &p.y, &p.z, &touched,
                        &close) != 5 ||
            close != ']' || !std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw StockError("the controller's probe report '" + reply + "' is not grbl's");
        if (touched != 1)
            throw StockError("the controller reports a probing cycle that touched nothing ('" +
                             reply + "')");
        touches.push_back(p);
    }
    return touches;
}

StockTop stock_top_from_touches(const std::vector<Point3>& touches, const StockProbePoints& points,
                                double repeatability_mm) {
    if (touches.size() != 2)
        throw StockError("the controller reported " + std::to_string(touches.size()) +
                         " probe touches, not 2 (the sheet's and the bed's)");
    const auto check_place = [](const Point3& touch, Point2 sent, const char* what) {
        if (std::abs(touch.x - sent.x) > kTouchPlaceToleranceMm ||
            std::abs(touch.y - sent.y) > kTouchPlaceToleranceMm)
            throw StockError(std::string("the probe touched ") + what + " at machine " +
                             machine_xy_text({touch.x, touch.y}) + ", not at " +
                             machine_xy_text(sent) + " where it was sent");
    };
    check_place(touches[0], points.on_sheet_mm, "the sheet");
    check_place(touches[1], points.beside_mm, "the bed");
    StockTop top;
    top.on_sheet_mm = touches[0];
    top.beside_mm = touches[1];
    top.surface_height_mm = touches[0].z - touches[1].z;
    top.sigma_mm = std::sqrt(2.0) * repeatability_mm;
    if (!(top.surface_height_mm > 0) || top.surface_height_mm > kMostTopMm)
        throw StockError("the sheet touched at machine Z" + number_text("%.3f", touches[0].z) +
                         ", the bed beside it at Z" + number_text("%.3f", touches[1].z) +
                         ": a top " + number_text("%.3f", top.surface_height_mm) +
                         " mm above the bed is no sheet's (0 to 200 mm): check that the first "
                         "point is on the sheet and the second on the bed");
    return top;
}

std::string stock_top_to_json(const StockTop& top) {
    const auto point3 = [](const Point3& p) { return nlohmann::json::array({p.x, p.y, p.z}); };
    const nlohmann::json j{{"schema", kStockTopSchema},
                           {"surface_height_mm", top.surface_height_mm},
                           {"sigma_mm", top.sigma_mm},
                           {"on_sheet_mm", point3(top.on_sheet_mm)},
                           {"beside_mm", point3(top.beside_mm)}};
    return j.dump(1) + "\n";
}

StockTop stock_top_from_json(const std::string& text, const std::string& source) {
    const auto j = parse_record(text, source, kStockTopSchema, "stock top");
    try {
        const auto point3 = [](const nlohmann::json& p) {
            return Point3{p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()};
        };
        StockTop top;
        top.surface_height_mm = j.at("surface_height_mm").get<double>();
        top.sigma_mm = j.at("sigma_mm").get<double>();
        top.on_sheet_mm = point3(j.at("on_sheet_mm"));
        top.beside_mm = point3(j.at("beside_mm"));
        if (!(top.surface_height_mm > 0) || top.surface_height_mm > kMostTopMm ||
            !(top.sigma_mm >= 0))
            throw RecordError(source + ": surface_height_mm is a sheet's top (0 to 200 mm)");
        return top;
    } catch (const nlohmann::json::exception& e) {
        throw RecordError(source + ": malformed stock top: " + e.what());
    }
}

std::string machine_xy_text(Point2 p) {
    // Appended piece by piece: GCC 12 at -O3 warns falsely on a literal + a temporary string.
    std::string text = "X";
    text += number_text("%.3f", p.x);
    text += " Y";
    text += number_text("%.3f", p.y);
    return text;
}

}  // namespace calbox::modes
