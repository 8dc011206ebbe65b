#pragma once
// A file the tests read whole: their inputs under CALBOX_TEST_DATA (test_data.hpp), the project's
// own examples and drawings.
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

namespace calbox::test {

// Throws std::runtime_error naming the file when it cannot be read.
inline std::string read_whole_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + path);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

}  // namespace calbox::test
