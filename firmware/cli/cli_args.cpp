#include "firmware/cli/cli_args.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "board/devices.hpp"

namespace calbox::cli {

Args::Args(std::map<std::string, std::string> values, std::set<std::string> flags,
           std::vector<std::string> positional)
    : values_(std::move(values)), flags_(std::move(flags)), positional_(std::move(positional)) {}

std::optional<std::string> Args::get(const std::string& name) const {
    const auto it = values_.find(name);
    if (it == values_.end()) return std::nullopt;
    return it->second;
}

std::string Args::require(const std::string& name) const {
    auto v = get(name);
    if (!v) throw UsageError("missing " + name);
    return *v;
}

double Args::number(const std::string& name, double fallback) const {
    const auto v = get(name);
    if (!v) return fallback;
    std::size_t used = 0;
    double d = 0;
    try {
        d = std::stod(*v, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used != v->size() || !std::isfinite(d))
        throw UsageError(name + " needs a number, not '" + *v + "'");
    return d;
}

void write_output_file(const std::string& path, const std::string& contents) {
    const std::filesystem::path p(path);
    const auto directory = p.has_parent_path() ? p.parent_path() : std::filesystem::path(".");
    if (!std::filesystem::is_directory(directory)) {
        throw std::runtime_error("cannot write " + path + ": no directory " + directory.string());
    }
    board::data_directory(directory)->replace_file(p.filename().string(), contents);
}

std::string read_input_file(const std::string& path, const std::string& what) {
    std::ifstream in(path, std::ios::binary);
    if (!in || std::filesystem::is_directory(path))
        throw std::runtime_error("cannot read " + what + " " + path);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

}  // namespace calbox::cli
