#include "core/modes/work_zero_link.hpp"

#include <sstream>

#include "core/modes/planar.hpp"
#include "core/modes/stock_top.hpp"

namespace calbox::modes {
namespace {

// "POS_OFFSET X 12.500000" -> 12.5 for `axis`; none when no reply says so.
std::optional<double> pos_offset_of(const std::vector<std::string>& replies, char axis) {
    for (const auto& reply : replies) {
        std::istringstream in(reply);
        std::string word, letter;
        double value = 0;
        if (in >> word >> letter >> value && word == "POS_OFFSET" && letter.size() == 1 &&
            (letter[0] == axis || letter[0] == axis + ('a' - 'A')))
            return value;
    }
    return std::nullopt;
}

}  // namespace

bool sets_work_zero(const std::string& firmware) {
    return firmware == "grbl" || firmware == "linuxcnc";
}

std::string work_zero_command(geometry::Point2 zero) {
    std::string line = "G10 L2 P1 ";
    line += machine_xy_text(zero);
    return line;
}

std::vector<std::string> work_zero_units_query(const std::string& firmware) {
    if (firmware == "linuxcnc") return {"get program_units"};
    return {};
}

std::string work_zero_units_refusal(const std::string& firmware,
                                    const std::vector<std::string>& replies) {
    if (firmware != "linuxcnc") return {};
    for (const auto& reply : replies)
        if (reply.rfind("PROGRAM_UNITS", 0) == 0) {
            if (reply == "PROGRAM_UNITS MM") return {};
            return "LinuxCNC's interpreter does not read millimetres now (" + reply +
                   "): the zero's X and Y would be read so; switch it to G21 first";
        }
    return "LinuxCNC did not say what units its interpreter reads (get program_units)";
}

std::vector<std::string> work_zero_exchange(const std::string& firmware, geometry::Point2 zero) {
    if (firmware == "linuxcnc")
        return {work_zero_command(zero), "get pos_offset X", "get pos_offset Y"};
    return {work_zero_command(zero), "$#"};
}

std::optional<geometry::Point2> work_zero_read_back(const std::string& firmware,
                                                    const std::vector<std::string>& replies) {
    if (firmware == "linuxcnc") {
        const auto x = pos_offset_of(replies, 'X');
        const auto y = pos_offset_of(replies, 'Y');
        if (!x || !y) return std::nullopt;
        return geometry::Point2{*x, *y};
    }
    return grbl_work_zero_of(replies, "G54");
}

std::string work_zero_report_name(const std::string& firmware) {
    return firmware == "linuxcnc" ? "linuxcncrsh's POS_OFFSET" : "$#";
}

}  // namespace calbox::modes
