#pragma once
// The twin LinuxCNC's linuxcncrsh on loopback, in front of the same twin bench: its text
// protocol as LinuxCNC's remote shell answers it (HELLO with the connect password, echo on until
// told off, SET ENABLE with the enable password before any control, SET MODE, SET WAIT_MODE and
// the older SET SET_WAIT, SET MDI answered once the line ran, its error read with GET ERROR; GET
// MACHINE, POS_OFFSET of the active system (G54) and PROGRAM_UNITS). Its url() is HOST:PORT.
// Faults from the scenario's [faults]: another password than the key file's (host_wrong_key),
// the machine off (host_printer_not_ready), silence from its n-th MDI line on
// (host_silent_at_request).
#include <memory>
#include <string>

#include "board/sim/twin_host.hpp"

namespace calbox::sim {

class LinuxCncTwin final : public TwinHostServer {
  public:
    // `passwords`: the connect and the enable password, as the box's key file holds them.
    LinuxCncTwin(std::shared_ptr<TwinBench> bench, const std::string& passwords, HostFaults faults);
    LinuxCncTwin(const LinuxCncTwin&) = delete;
    LinuxCncTwin& operator=(const LinuxCncTwin&) = delete;
    ~LinuxCncTwin() override;
    std::string url() const override;  // "127.0.0.1:PORT"
    int connections() const;           // the box's, accepted so far

  private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace calbox::sim
