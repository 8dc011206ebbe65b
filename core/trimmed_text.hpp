#pragma once
// A line or a value without the white space around it: the one trim core's readers of machine
// files share (Klipper's printer.cfg, Marlin's and RepRapFirmware's captures).
#include <cctype>
#include <string>
#include <string_view>

namespace calbox {

inline std::string trimmed(std::string_view text) {
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front())))
        text.remove_prefix(1);
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back())))
        text.remove_suffix(1);
    return std::string(text);
}

}  // namespace calbox
