// The one place on the box's side that reads the machine's kind.
#include <sstream>
#include <stdexcept>

#include "firmware/modes/delta_mode.hpp"
#include "firmware/modes/galvo_mode.hpp"
#include "firmware/modes/planar_mode.hpp"

namespace calbox::firmware {

std::unique_ptr<CycleMode> make_cycle_mode(const models::MachineFile& machine, CycleSteps& steps) {
    if (machine.is_delta()) return std::make_unique<DeltaCycleMode>(machine, steps);
    if (machine.is_galvo()) return std::make_unique<GalvoCycleMode>(machine, steps);
    if (machine.is_planar()) return std::make_unique<PlanarCycleMode>(machine, steps);
    throw std::invalid_argument("the cycle runs the delta, galvo and planar modes, not a " +
                                machine.kind);
}

std::vector<std::string> lines_of(const std::string& text) {
    std::vector<std::string> lines;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    return lines;
}

std::string joined(const std::vector<std::string>& lines) {
    std::string out;
    for (const auto& l : lines) out += l + "\n";
    return out;
}

}  // namespace calbox::firmware
