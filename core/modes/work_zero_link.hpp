#pragma once
// The controller's G54 zero set over the machine's link and read back, in each controller's own
// words: grbl's G10 L2 P1 and its `$#` report; LinuxCNC's G10 L2 P1 by MDI and linuxcncrsh's
// POS_OFFSET (the active system's offset, G92's included: what a job that selects no system
// runs at), after its PROGRAM_UNITS says the interpreter reads millimetres.
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/types.hpp"

namespace calbox::modes {

// Whether the box sets the work zero of a machine with this firmware ("grbl", "linuxcnc").
bool sets_work_zero(const std::string& firmware);

// "G10 L2 P1 X-250.000 Y-180.500": G54's X and Y zero at `zero`, machine coordinates in mm.
std::string work_zero_command(geometry::Point2 zero);

// Asked before the zero is sent (LinuxCNC: "get program_units"); none for grbl.
std::vector<std::string> work_zero_units_query(const std::string& firmware);
// Empty when the answers say the controller reads millimetres (or nothing was asked); otherwise
// why the zero is not sent, in one line.
std::string work_zero_units_refusal(const std::string& firmware,
                                    const std::vector<std::string>& replies);

// What sets the zero and reads it back: the command, then the firmware's report.
std::vector<std::string> work_zero_exchange(const std::string& firmware, geometry::Point2 zero);
// G54's zero as the replies to that exchange report it; empty when they hold none.
std::optional<geometry::Point2> work_zero_read_back(const std::string& firmware,
                                                    const std::vector<std::string>& replies);
// "$#", "linuxcncrsh's POS_OFFSET": how the read-back is named in messages.
std::string work_zero_report_name(const std::string& firmware);

}  // namespace calbox::modes
