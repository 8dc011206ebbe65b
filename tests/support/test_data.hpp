#pragma once
// Inputs made outside the project, read where they are (CALBOX_TEST_DATA) and never copied in.
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace calbox::test {

inline std::string test_data_path(const std::string& relative) {
    return std::string(CALBOX_TEST_DATA) + "/" + relative;
}

inline std::string read_test_data(const std::string& relative) {
    const std::string path = test_data_path(relative);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + path);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

}  // namespace calbox::test
