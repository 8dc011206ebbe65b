#pragma once
// The twin RepRapFirmware printer on a Duet, on loopback: the same twin bench as over the pty,
// reached through the board's own web API (rr_connect with its password and a session key,
// rr_gcode and rr_reply, rr_upload with its CRC32, the object model's state and job), as
// RepRapFirmware 3 answers them; or, on a Duet with an SBC (TwinHostSettings::duet_sbc), through
// DuetSoftwareFramework's (/machine/connect, /machine/code with the code's reply, PUT
// /machine/file, /machine/model), which serves no rr_ request. Uploaded jobs are kept in a
// directory of the board's own (its SD card). Faults from the scenario's [faults].
#include <filesystem>
#include <memory>
#include <string>

#include "board/sim/twin_host.hpp"

namespace calbox::sim {

class DuetTwin final : public TwinHostServer {
  public:
    DuetTwin(std::shared_ptr<TwinBench> bench, std::filesystem::path host_dir,
             TwinHostSettings settings);
    DuetTwin(const DuetTwin&) = delete;
    DuetTwin& operator=(const DuetTwin&) = delete;
    ~DuetTwin() override;
    std::string url() const override;
    // Sessions the box closed (rr_disconnect, /machine/disconnect).
    int sessions_closed() const;

  private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace calbox::sim
