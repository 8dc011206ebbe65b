#pragma once
// The one factory of machine links: the link the machine file's [link] says.
#include <memory>

#include "core/models/machine_file.hpp"
#include "firmware/links/gcode_host.hpp"
#include "firmware/links/machine_link.hpp"
#include "firmware/settings/settings_table.hpp"
#include "hal/clock.hpp"
#include "hal/network.hpp"
#include "hal/serial_port.hpp"

namespace calbox::firmware {

// The machine's link as the configuration sets it over the machine file's [link]: each value
// left at its default keeps the machine file's.
struct LinkSettings {
    std::string kind = "machine";  // machine (the machine file's) | serial | moonraker | octoprint
                                   // | duet | linuxcnc
    std::string url;               // a host's
    std::string key_file;          // the host's API key, alone in the file
    std::string ca_file;           // an https host's certificate authority (PEM)
    // `machine`'s [link] with these over it; throws ConfigError when they do not fit its firmware.
    models::MachineLinkSettings over(const models::MachineFile& machine) const;
};

// The machine link's table of the configuration: [link].
SettingsTable<LinkSettings> link_settings_table();

// The machine link the machine file's [link] says: G-code streamed over the board's serial port
// (numbered and checksummed, or plain lines for grbl, as its firmware reads them), or a host's
// API over the `network` (HTTP; linuxcncrsh's text over TCP). Throws std::runtime_error naming
// what is missing (no serial port, no network; a key file that cannot be read).
std::unique_ptr<MachineLink> make_machine_link(const models::MachineFile& machine,
                                               hal::SerialPort* port, hal::Network* network,
                                               hal::Clock& clock, GcodeHostSettings serial,
                                               const GcodeHost::Log& log);

}  // namespace calbox::firmware
