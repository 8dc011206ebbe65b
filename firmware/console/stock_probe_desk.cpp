#include "firmware/console/stock_probe_desk.hpp"

#include <exception>
#include <memory>

#include "core/modes/stock.hpp"
#include "core/modes/stock_top.hpp"
#include "core/number_text.hpp"
#include "firmware/console/job_desk.hpp"
#include "firmware/cycle/cycle.hpp"

namespace calbox::firmware {

struct StockProbeDesk::Sent {
    modes::StockProbePoints points;
    double repeatability_mm = 0;
};

StockProbeDesk::StockProbeDesk(Cycle& cycle, MachineLink& link, hal::Storage& data, Notice notice)
    : cycle_(cycle), link_(link), data_(data), notice_(std::move(notice)) {}

namespace {

constexpr const char* kUsage = "usage: probe stock [ON_X,ON_Y BESIDE_X,BESIDE_Y] [confirm]";

// The two points: as given (machine X,Y, the sheet's first), or at the found sheet's corner.
modes::StockProbePoints points_of(const std::vector<std::string>& given, hal::Storage& data) {
    if (given.size() == 2) {
        modes::StockProbePoints points;
        for (std::size_t i = 0; i < 2; ++i) {
            const auto at = one_xy_of(given[i]);
            if (!at)
                throw ConsoleRefused("probe stock: '" + given[i] +
                                     "' is not X,Y (machine coordinates, mm)");
            (i == 0 ? points.on_sheet_mm : points.beside_mm) = *at;
        }
        points.from = "as given";
        return points;
    }
    if (!given.empty()) throw ConsoleRefused(kUsage);
    const auto text = data.read_file(kFoundStockFile);
    if (!text)
        throw ConsoleRefused(
            "probe stock: no sheet found on the bed to probe by: take a bed photo with the sheet "
            "in view (bed photo), or give the points (ON_X,ON_Y on the sheet, BESIDE_X,BESIDE_Y "
            "on the bed)");
    try {
        return modes::probe_points_at_corner(modes::stock_from_json(*text, kFoundStockFile).stock,
                                             kFoundStockFile);
    } catch (const std::exception& e) {
        throw ConsoleRefused("probe stock: " + std::string(e.what()));
    }
}

}  // namespace

ConsoleCommand StockProbeDesk::command() {
    return {
        "probe stock", "probe stock [ON_X,ON_Y BESIDE_X,BESIDE_Y] [confirm]",
        "the stock's top above the bed by the machine's touch probe ([touch_probe], grbl's "
        "G38.2): the tool lifted to the clear height, probed down on the sheet at ON and on the "
        "bed at BESIDE (machine X,Y; by default 10 mm in and out from the corner of the sheet "
        "the last bed photo found); shown first, sent only with confirm; the height kept for "
        "the next bed photo (stock-top.json)",
        [this](const std::vector<std::string>& words, std::string_view, ConsoleReply& reply) {
            const auto [given, confirmed] = words_and_confirm(words, 2);
            const auto& machine = cycle_.machine();
            if (!machine.touch_probe)
                throw ConsoleRefused(
                    "probe stock: the machine file has no [touch_probe] (a router's probe on "
                    "grbl, G38.2): give the stock's top to bed photo SURFACE_MM");
            const auto points = points_of(given, data_);
            for (const auto at : {points.on_sheet_mm, points.beside_mm})
                if (!inside_stated_travel(machine, at))
                    throw ConsoleRefused("probe stock: machine " + modes::machine_xy_text(at) +
                                         " is beyond the machine file's travel (or it gives "
                                         "none)");
            const auto lines = modes::touch_probe_commands(*machine.touch_probe, points);
            std::string sent;
            for (const auto& l : lines) sent += (sent.empty() ? "" : "; ") + l;
            reply.data = {{"commands", lines}, {"sent", confirmed}, {"from", points.from}};
            const std::string what =
                "the sheet at machine " + modes::machine_xy_text(points.on_sheet_mm) +
                ", the bed at " + modes::machine_xy_text(points.beside_mm) + " (" + points.from +
                "), from machine Z" + number_text("%.3f", machine.touch_probe->clear_z_mm);
            if (!confirmed) {
                reply.text = "would probe " + what + ": '" + sent +
                             "': say it again with confirm, the probe ready";
                return;
            }
            if (busy_ || cycle_.state() != CycleState::idle || link_.busy())
                throw ConsoleRefused(
                    "probe stock: the machine link is busy: try again when the box is idle");
            busy_ = true;
            sent_ = std::make_shared<Sent>(Sent{points, machine.touch_probe->repeatability_mm});
            link_.send_commands(lines, [this](const JobOutcome& outcome) { probed(outcome); });
            reply.text = "probing " + what;
        }};
}

void StockProbeDesk::probed(const JobOutcome& outcome) {
    busy_ = false;
    const auto sent = std::move(sent_);
    // A failed probe leaves no height from an earlier one for a bed photo to take.
    const auto refused = [this](const std::string& why) {
        try {
            data_.remove_file(kProbedStockTopFile);
        } catch (const std::exception&) {
        }
        notice_("probe stock: " + why + "; no height kept");
    };
    if (!outcome.ok) {
        refused("the controller stopped: " + outcome.error +
                " (check the probe, the tool's place and the alarm)");
        return;
    }
    try {
        const auto top = modes::stock_top_from_touches(modes::grbl_probe_touches(outcome.replies),
                                                       sent->points, sent->repeatability_mm);
        data_.replace_file(kProbedStockTopFile, modes::stock_top_to_json(top));
        notice_("probe stock: the sheet's top " + number_text("%.3f", top.surface_height_mm) +
                " mm above the bed (+/-" + number_text("%.3f", top.sigma_mm) +
                "; touched at machine Z" + number_text("%.3f", top.on_sheet_mm.z) +
                " on the sheet, Z" + number_text("%.3f", top.beside_mm.z) +
                " beside it), kept as " + kProbedStockTopFile + " for the next bed photo");
    } catch (const std::exception& e) {
        refused(e.what());
    }
}

}  // namespace calbox::firmware
