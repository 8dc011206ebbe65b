#include "firmware/cli/cli_args.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "board/devices.hpp"

namespace calbox::cli {

Args::Args(const std::vector<std::string>& words, const std::set<std::string>& valued,
           const std::set<std::string>& flags) {
    for (std::size_t i = 0; i < words.size(); ++i) {
        const std::string& w = words[i];
        if (w.size() > 1 && w[0] == '-' &&
            !(w.size() > 1 && (std::isdigit(static_cast<unsigned char>(w[1])) || w[1] == '.'))) {
            if (flags.count(w)) {
                flags_.insert(w);
                continue;
            }
            if (!valued.count(w)) throw UsageError("unknown option " + w);
            if (i + 1 >= words.size()) throw UsageError(w + " needs a value");
            if (values_.count(w)) throw UsageError(w + " given twice");
            values_[w] = words[++i];
            continue;
        }
        positional_.push_back(w);
    }
}

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

int dispatch(const std::vector<std::string>& words, const char* help, const char* group,
             const std::vector<std::pair<std::string, Command>>& commands) {
    const bool wants_help = std::any_of(words.begin(), words.end(), [](const std::string& w) {
        return w == "--help" || w == "-h";
    });
    if (words.empty() || wants_help) {
        std::cout << help;
        return words.empty() ? 2 : 0;
    }
    const std::vector<std::string> rest(words.begin() + 1, words.end());
    std::string names;
    for (const auto& [name, run] : commands) {
        if (words[0] == name) return run(rest);
        names += (names.empty() ? "" : ", ") + name;
    }
    throw UsageError("unknown " + std::string(group) + " command '" + words[0] + "' (" + names +
                     ")");
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
