#include "firmware/modes/klipper_host.hpp"

#include <memory>
#include <utility>

namespace calbox::firmware {

void restore_printer_cfg(CycleSteps& steps, const std::string& backup,
                         std::function<bool(const std::string& now)> ours, const std::string& why) {
    steps.log(why + "; checking printer.cfg on the host", hal::LogLevel::warning);
    steps.ask_machine(
        [](MachineLink& m, MachineLink::Done done) { m.read_config_file(std::move(done)); },
        [&steps, backup, ours = std::move(ours), why](const JobOutcome& now) {
            if (!now.ok) {
                steps.fail(why + "; printer.cfg could not be read to check it: " + now.error);
                return;
            }
            if (now.text == backup) {
                steps.fail(why + " (printer.cfg was not changed)");
                return;
            }
            if (!ours(now.text)) {
                steps.fail(why + " (printer.cfg on the host is someone else's now: left as it is)");
                return;
            }
            steps.ask_machine(
                [backup, current = now.text](MachineLink& m, MachineLink::Done done) {
                    m.replace_config_file(backup, current, std::move(done));
                },
                [&steps, why](const JobOutcome& restored) {
                    steps.fail(restored.ok
                                   ? why + " (the previous printer.cfg was restored)"
                                   : why + "; restoring the previous printer.cfg failed too: " +
                                         restored.error);
                },
                false);
        },
        false);
}

void write_printer_cfg(CycleSteps& steps, PrinterCfgWrite write) {
    steps.enter(CycleState::apply,
                "backing up printer.cfg through " + steps.machine_link().describe());
    auto shared = std::make_shared<PrinterCfgWrite>(std::move(write));
    steps.ask_machine(
        [](MachineLink& m, MachineLink::Done done) { m.read_config_file(std::move(done)); },
        [&steps, shared](const JobOutcome& read) {
            std::string updated;
            try {
                updated = shared->update(read.text);
            } catch (const std::exception& e) {
                steps.fail(std::string("apply: ") + e.what() + " (nothing was written)");
                return;
            }
            if (!steps.keep(shared->backup_record, read.text) ||
                !steps.keep(shared->updated_record, updated))
                return;
            steps.log(shared->writing);
            steps.ask_machine(
                [updated, backup = read.text](MachineLink& m, MachineLink::Done done) {
                    m.replace_config_file(updated, backup, std::move(done));
                },
                [shared, updated, backup = read.text](const JobOutcome& replaced) {
                    if (!replaced.ok) {
                        shared->refused(backup, updated, "apply: " + replaced.error);
                        return;
                    }
                    shared->written(backup, updated);
                },
                false);
        },
        true);
}

void put_back_printer_cfg(CycleSteps& steps, const std::string& backup,
                          std::function<void()> then) {
    steps.ask_machine(
        [](MachineLink& m, MachineLink::Done done) { m.read_config_file(std::move(done)); },
        [&steps, backup, then = std::move(then)](const JobOutcome& now) {
            steps.ask_machine(
                [backup, current = now.text](MachineLink& m, MachineLink::Done done) {
                    m.replace_config_file(backup, current, std::move(done));
                },
                [then](const JobOutcome&) { then(); }, true);
        },
        true);
}

}  // namespace calbox::firmware
