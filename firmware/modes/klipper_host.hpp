#pragma once
// printer.cfg on a Klipper host, as the modes that set Klipper through it share it (the delta
// mode's geometry, the planar mode's travel and skew): the file put back after a failed apply,
// and a revert's upload of a cycle's backup.
#include <functional>
#include <string>

#include "firmware/cycle/cycle_mode.hpp"

namespace calbox::firmware {

// After a failed apply the host holds the old file, one the box's apply left (`ours`), or
// someone else's: only the box's is replaced by `backup`, so that printer.cfg ends untouched or
// fully the backup. The cycle then fails with `why` and what became of the file.
void restore_printer_cfg(CycleSteps& steps, const std::string& backup,
                         std::function<bool(const std::string& now)> ours, const std::string& why);

// A revert: printer.cfg on the host replaced whole by `backup` (Klipper restarted and ready
// again), then `then`.
void put_back_printer_cfg(CycleSteps& steps, const std::string& backup, std::function<void()> then);

}  // namespace calbox::firmware
