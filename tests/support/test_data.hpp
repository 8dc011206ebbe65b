#pragma once
// Inputs made outside the project, read where they are (CALBOX_TEST_DATA) and never copied in.
#include <string>

#include "tests/support/whole_file.hpp"

namespace calbox::test {

inline std::string test_data_path(const std::string& relative) {
    return std::string(CALBOX_TEST_DATA) + "/" + relative;
}

inline std::string read_test_data(const std::string& relative) {
    return read_whole_file(test_data_path(relative));
}

}  // namespace calbox::test
