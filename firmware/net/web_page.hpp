#pragma once
// The box's web page: every asset served by the box itself, nothing fetched from elsewhere.
#include <string_view>

namespace calbox::firmware {

std::string_view web_page_html();
std::string_view web_page_script();
std::string_view web_page_style();

}  // namespace calbox::firmware
