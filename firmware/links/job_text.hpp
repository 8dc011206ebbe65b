#pragma once
// A job's text as the links send it and the modes make it: lines without their newlines, and
// lines joined with one after each.
#include <string>
#include <vector>

namespace calbox::firmware {

std::vector<std::string> lines_of(const std::string& text);
std::string joined(const std::vector<std::string>& lines);  // each line ended by a newline

}  // namespace calbox::firmware
