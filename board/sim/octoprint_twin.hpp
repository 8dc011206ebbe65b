#pragma once
// The twin Marlin printer behind its OctoPrint host, on loopback: the same twin bench as over the
// pty, reached through OctoPrint's REST API and its push socket (/sockjs/websocket) whose
// terminal logs carry what the printer says, with an API key; its application-keys plugin
// grants the key a second after it is asked (as if the owner clicked Allow). Uploaded jobs are
// kept in a directory of the host's own. Faults from the scenario's [faults].
#include <filesystem>
#include <memory>
#include <string>

#include "board/sim/twin_host.hpp"

namespace calbox::sim {

class OctoPrintTwin final : public TwinHostServer {
  public:
    OctoPrintTwin(std::shared_ptr<TwinBench> bench, std::filesystem::path host_dir,
                  TwinHostSettings settings);
    OctoPrintTwin(const OctoPrintTwin&) = delete;
    OctoPrintTwin& operator=(const OctoPrintTwin&) = delete;
    ~OctoPrintTwin() override;
    std::string url() const override;

  private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace calbox::sim
