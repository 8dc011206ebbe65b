#pragma once
// The calbox command line: options are "--name value" (or "-o value"), everything else is
// positional. Each command states which options it takes; anything else is an error.
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace calbox::cli {

class UsageError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

class Args {
  public:
    Args(const std::vector<std::string>& words, const std::set<std::string>& valued,
         const std::set<std::string>& flags);
    std::optional<std::string> get(const std::string& name) const;
    std::string require(const std::string& name) const;
    bool flag(const std::string& name) const { return flags_.count(name) != 0; }
    const std::vector<std::string>& positional() const { return positional_; }
    // A number option: absent gives `fallback`; present must parse completely.
    double number(const std::string& name, double fallback) const;

  private:
    std::map<std::string, std::string> values_;
    std::set<std::string> flags_;
    std::vector<std::string> positional_;
};

// One command group ("calbox sim ..."): --help anywhere prints `help`; the first word picks the
// command from `commands`; no word at all prints the help and returns 2.
using Command = int (*)(const std::vector<std::string>& rest);
int dispatch(const std::vector<std::string>& words, const char* help, const char* group,
             const std::vector<std::pair<std::string, Command>>& commands);

// Writes a whole output file atomically (sibling + rename): a failed run leaves no half file.
void write_output_file(const std::string& path, const std::string& contents);
std::string read_input_file(const std::string& path, const std::string& what);

int run_sim(const std::vector<std::string>& words);         // "calbox sim ..."
int run_camera(const std::vector<std::string>& words);      // "calbox camera ..."
int run_detect(const std::vector<std::string>& words);      // "calbox detect ..."
int run_target(const std::vector<std::string>& words);      // "calbox target ..."
int run_solve(const std::vector<std::string>& words);       // "calbox solve ..."
int run_measure(const std::vector<std::string>& words);     // "calbox measure ..."
int run_compensate(const std::vector<std::string>& words);  // "calbox compensate ..."
int run_appliance(const std::vector<std::string>& words);   // "calbox run ..."
int run_revert(const std::vector<std::string>& words);      // "calbox revert ..."
int run_machine(const std::vector<std::string>& words);     // "calbox machine ..."

}  // namespace calbox::cli
