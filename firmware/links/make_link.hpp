#pragma once
// The one factory of machine links: the link the machine file's [link] says.
#include <memory>

#include "core/models/machine_file.hpp"
#include "firmware/links/gcode_host.hpp"
#include "firmware/links/machine_link.hpp"
#include "hal/clock.hpp"
#include "hal/http.hpp"
#include "hal/serial_port.hpp"

namespace calbox::firmware {

// The machine link the machine file's [link] says: G-code streamed over the board's serial port,
// or a host's API over `http`. Throws std::runtime_error naming what is missing (no serial port,
// no network; a key file that cannot be read).
std::unique_ptr<MachineLink> make_machine_link(const models::MachineLinkSettings& link,
                                               hal::SerialPort* port, hal::HttpClient* http,
                                               hal::Clock& clock, GcodeHostSettings serial,
                                               const GcodeHost::Log& log);

}  // namespace calbox::firmware
