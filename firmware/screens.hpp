#pragma once
// What the 128x64 display shows: a title line and up to four text lines.
#include <string>
#include <vector>

#include "hal/display.hpp"

namespace calbox::firmware {

hal::MonoBitmap text_screen(const std::string& title, const std::vector<std::string>& lines);

}  // namespace calbox::firmware
