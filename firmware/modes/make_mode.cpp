// The one place on the box's side that chooses a mode by the machine's kind.
#include <stdexcept>

#include "firmware/modes/delta_mode.hpp"
#include "firmware/modes/galvo_mode.hpp"
#include "firmware/modes/planar_mode.hpp"

namespace calbox::firmware {

std::unique_ptr<CycleMode> make_cycle_mode(const models::MachineFile& machine, CycleSteps& steps) {
    // One case per family of core/models/machine_kinds.hpp: a new family without its mode is
    // a switch the compiler refuses (-Wswitch, an error here).
    switch (machine.family()) {
        case models::MachineFamily::delta:
            return std::make_unique<DeltaCycleMode>(machine, steps);
        case models::MachineFamily::galvo:
            return std::make_unique<GalvoCycleMode>(machine, steps);
        case models::MachineFamily::planar:
            return std::make_unique<PlanarCycleMode>(machine, steps);
    }
    throw std::invalid_argument("the cycle has no mode for a " + machine.kind);
}

// The galvo's result is its table (ModeResult::table), the planar mode's its kept model: only
// the delta's carries values.
std::vector<std::string> mode_result_names() {
    return DeltaCycleMode::result_names();
}

std::vector<ModeTable> mode_tables() {
    return {GalvoCycleMode::result_table()};
}

}  // namespace calbox::firmware
