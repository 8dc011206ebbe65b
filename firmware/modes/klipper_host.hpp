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

// An apply's write of printer.cfg, as every mode that sets Klipper through it makes it: the file
// read (the backup), `update` makes the new text from it (an exception: the cycle fails, nothing
// written), both kept in the records as `backup_record` and `updated_record`, `writing` logged,
// the new file written and Klipper restarted; then `written(backup, updated)`. A write the host
// refuses goes to `refused(backup, updated, why)`, which puts the file back as the mode knows its
// own (restore_printer_cfg).
struct PrinterCfgWrite {
    std::function<std::string(const std::string& read)> update;
    std::string backup_record, updated_record;
    std::string writing;
    std::function<void(const std::string& backup, const std::string& updated)> written;
    std::function<void(const std::string& backup, const std::string& updated,
                       const std::string& why)>
        refused;
};
void write_printer_cfg(CycleSteps& steps, PrinterCfgWrite write);

// A revert: printer.cfg on the host replaced whole by `backup` (Klipper restarted and ready
// again), then `then`.
void put_back_printer_cfg(CycleSteps& steps, const std::string& backup, std::function<void()> then);

}  // namespace calbox::firmware
