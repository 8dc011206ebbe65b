#include "core/jobs/cutter_rules.hpp"

#include <algorithm>

namespace calbox::jobs::cutter_rules {

using job_words::Code;

std::string refusal(const std::string& what) {
    return what +
           " under cutter radius compensation: calbox carries it through straight moves and "
           "arcs in the XY plane (G17); have the CAM write the compensated path";
}

bool reframes_position(const job_words::ReadLine& r) {
    return std::any_of(r.codes.begin(), r.codes.end(), [](Code c) {
        return c.is(10) || c.is(28) || c.is(30) || c.is(52) || c.is(53) || c.number == 92 ||
               (c.number >= 54 && c.number <= 59);
    });
}

int compensation_turned_on(const job_words::ReadLine& r) {
    const auto has = [&r](int n) {
        return std::any_of(r.codes.begin(), r.codes.end(), [n](Code c) {
            return c.number == n && (c.subcode == -1 || c.subcode == 1);
        });
    };
    return has(41) ? 1 : has(42) ? -1 : 0;
}

std::string mode_change_refusal(const job_words::ReadLine& r) {
    for (const Code c : r.codes) {
        const char* change = c.is(20) || c.is(21)         ? "units"
                             : c.number == 43 || c.is(49) ? "the tool length offset (G43, G49)"
                             : c.number == 61 || c.is(64) ? "the path control mode (G61, G64)"
                                                          : nullptr;
        if (change != nullptr)
            return std::string("a change of ") + change +
                   " under cutter radius compensation: LinuxCNC refuses it too";
    }
    return "";
}

std::string arc_words_refusal(const gcode::Line& l, bool moves) {
    if (!moves)
        return l.has('I') || l.has('J') || l.has('R') ? refusal("an arc without X, Y or Z") : "";
    if (const auto turns = l.value('P'); turns && *turns != 1)
        return refusal("an arc of more than one turn (P)");
    if (!l.has('I') && !l.has('J') && !l.has('R'))
        return "an arc without its centre (I, J) or radius (R): LinuxCNC refuses it too";
    return "";
}

}  // namespace calbox::jobs::cutter_rules
