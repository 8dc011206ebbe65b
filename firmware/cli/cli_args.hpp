#pragma once
// The calbox command line. Each command declares its options once, as a Command: the parser
// (CLI11, in main.cpp) makes the command's usage, its --help and its errors for unknown,
// missing, repeated or malformed options from that declaration, and hands the command what
// was given as Args.
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace calbox::cli {

// Bad use of a command (as against bad input files): exit status 2, and the --help to see
// ("calbox solve delta"; the top level's unless the parser knows the command).
class UsageError : public std::runtime_error {
  public:
    explicit UsageError(const std::string& what, std::string help_of = "calbox")
        : std::runtime_error(what), help_of_(std::move(help_of)) {}
    const std::string& help_of() const { return help_of_; }

  private:
    std::string help_of_;
};

// What a command was given, by the names its options are declared with ("--machine", "-o").
class Args {
  public:
    Args(std::map<std::string, std::string> values, std::set<std::string> flags,
         std::vector<std::string> positional);
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

enum class Given {
    optional,   // --name VALUE, may be left out
    required,   // --name VALUE, must be there
    flag,       // --name alone
    word,       // one positional argument, required (its name in capitals: IMAGE)
    words,      // one or more positional arguments (IMAGES)
    any_words,  // positional arguments, none or more
};

struct Option {
    std::string name;   // "--machine", "-o"; a positional argument's name: "IMAGES"
    std::string value;  // the value as the usage names it: "printer.toml", "MM"
    std::string help;
    Given given = Given::optional;
};

struct Command {
    std::string path;     // "solve delta"; a command of one word: "compensate"
    std::string summary;  // one line, listed by `calbox solve --help`
    std::vector<Option> options;
    std::string details;  // what it does and what it refuses, after the options in --help
    int (*run)(const Args& args) = nullptr;
};

// Each file's commands, in the order --help lists them.
std::vector<Command> appliance_commands();  // run, revert
std::vector<Command> camera_commands();
std::vector<Command> detect_commands();
std::vector<Command> target_commands();
std::vector<Command> measure_commands();
std::vector<Command> solve_commands();
std::vector<Command> compensate_commands();
std::vector<Command> machine_commands();
std::vector<Command> sim_commands();
std::vector<Command> view_commands();  // view bed

// Writes a whole output file atomically (sibling + rename): a failed run leaves no half file.
void write_output_file(const std::string& path, const std::string& contents);
std::string read_input_file(const std::string& path, const std::string& what);

}  // namespace calbox::cli
