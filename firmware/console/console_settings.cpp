// The console's table of the configuration: [console], the port it is read on.
#include <string>

#include "firmware/console/console.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;
using setting_text::choice;
using setting_text::one_line;

const SettingKey<ConsoleSettings> kConsoleKeys[] = {
    {{"device",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "the console's device: a serial device's path, \"pty\" (a pseudo-terminal, its path "
      "logged and linked as DATA/console), \"stdin\" (standard input when it is a terminal), "
      "or empty for none"},
     [](const ConsoleSettings& s) { return s.device; },
     [](ConsoleSettings& s, const KeyInfo&, std::string_view t) { s.device = one_line(t); }},
    {{"baud", K::choice, "baud", 0, 0, "9600|19200|38400|57600|115200|230400", true,
      "the console UART's speed"},
     [](const ConsoleSettings& s) { return std::to_string(s.baud); },
     [](ConsoleSettings& s, const KeyInfo& k, std::string_view t) {
         s.baud = std::stoi(choice(k, t));
     }},
};

}  // namespace

SettingsTable<ConsoleSettings> console_settings_table() {
    return {"console", kConsoleKeys};
}

}  // namespace calbox::firmware
