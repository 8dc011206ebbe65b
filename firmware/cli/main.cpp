// calbox: one binary; each command exposes one step of the calibration cycle, or the appliance.
// The commands declare their options (cli_args.hpp); this file hands them to CLI11, which makes
// every usage line, --help and option error from those declarations.
#include <malloc.h>

#include <CLI/CLI.hpp>
#include <cctype>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "board/devices.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/mode_verbs.hpp"
#include "firmware/cli/version.hpp"

namespace {

using calbox::cli::Args;
using calbox::cli::Command;
using calbox::cli::Given;
using calbox::cli::UsageError;

// The first word of the commands of two words, as `calbox --help` lists them.
struct Group {
    const char* name;
    const char* summary;
};
const Group kGroups[] = {
    {"camera", "intrinsic calibration and the bed plane"},
    {"detect", "what the box sees in an image"},
    {"target", "a calibration target, or a job from a drawing"},
    {"measure", "measure the made target in photos"},
    {"solve", "fit the machine's model and write the correction"},
    {"machine", "a machine file from the printer's own files"},
    {"sim", "the digital twin"},
    {"view", "what the camera sees, in the machine's coordinates"},
};

// The help's last lines: the modes (each declared with its verbs), and what every command returns.
std::string footer() {
    return calbox::cli::modes_line(90) +
           "\n\nEvery command exits 0 on success, and non-zero with one line on standard error "
           "on failure.";
}

std::vector<Command> all_commands() {
    std::vector<Command> all;
    for (auto* commands :
         {calbox::cli::appliance_commands, calbox::cli::camera_commands,
          calbox::cli::detect_commands, calbox::cli::target_commands, calbox::cli::measure_commands,
          calbox::cli::solve_commands, calbox::cli::compensate_commands,
          calbox::cli::machine_commands, calbox::cli::sim_commands, calbox::cli::view_commands})
        for (auto& c : commands()) all.push_back(std::move(c));
    return all;
}

// One declared option as CLI11 holds it, to read back what was given.
struct Declared {
    CLI::Option* option;
    Given given;
};

struct CommandLine {
    CLI::App app{"calbox: calibrates machines from photos of what they make", "calbox"};
    std::vector<Command> commands = all_commands();
    std::vector<CLI::App*> apps;                  // one a command, as `commands`
    std::vector<std::vector<Declared>> declared;  // one a command, as `commands`

    CommandLine() {
        app.require_subcommand(1);
        app.footer(footer());
        app.set_version_flag("--version", std::string("calbox ") + calbox::build_version());
        app.get_formatter()->column_width(34);
        for (const auto& c : commands) add(c);
    }

    CLI::App* parent_of(const std::string& path, std::string& verb) {
        const auto space = path.find(' ');
        if (space == std::string::npos) {
            verb = path;
            return &app;
        }
        const std::string group = path.substr(0, space);
        verb = path.substr(space + 1);
        for (auto* existing : app.get_subcommands({}))
            if (existing->get_name() == group) return existing;
        for (const auto& g : kGroups)
            if (group == g.name) {
                auto* made = app.add_subcommand(g.name, g.summary);
                made->require_subcommand(1);
                return made;
            }
        throw std::logic_error("command '" + path + "' has no group");
    }

    void add(const Command& c) {
        std::string verb;
        CLI::App* sub = parent_of(c.path, verb)->add_subcommand(verb, c.summary);
        if (!c.details.empty()) sub->footer(c.details);
        std::vector<Declared> options;
        for (const auto& o : c.options) {
            CLI::Option* added = nullptr;
            switch (o.given) {
                case Given::flag:
                    added = sub->add_flag(o.name)->description(o.help);
                    break;
                case Given::optional:
                case Given::required:
                    added = sub->add_option(o.name, o.help)->type_name(o.value);
                    if (o.given == Given::required) added->required();
                    break;
                case Given::word:
                    added = sub->add_option(o.name, o.help)->type_name("")->required();
                    break;
                case Given::words:
                case Given::any_words:
                    added = sub->add_option(o.name, o.help)
                                ->type_name("")
                                ->expected(o.given == Given::words ? 1 : 0,
                                           CLI::detail::expected_max_vector_size)
                                ->allow_extra_args();
                    if (o.given == Given::words) added->required();
                    break;
            }
            options.push_back({added, o.given});
        }
        apps.push_back(sub);
        declared.push_back(std::move(options));
    }

    // The command the words chose, or the deepest group they reached, and the words above it.
    struct Reached {
        const CLI::App* app;
        std::string above;  // "calbox solve" for solve delta; empty for the top level
        std::string path() const {
            return above.empty() ? "calbox" : above + " " + app->get_name();
        }
    };
    Reached reached() const {
        Reached r{&app, {}};
        for (auto chosen = app.get_subcommands(); !chosen.empty();
             chosen = r.app->get_subcommands()) {
            r.above = r.path();
            r.app = chosen.front();
        }
        return r;
    }

    // Words that do not name a command, or options the command does not take, are named
    // before CLI11 reads the options: it would report a missing option first, or call an
    // unknown command an unexpected argument.
    void check_words(const std::vector<std::string>& words) const {
        const CLI::App* at = &app;
        std::string path = "calbox";
        const auto refuse = [&path](const std::string& what) {
            throw UsageError(path == "calbox" ? what : path.substr(7) + ": " + what, path);
        };
        std::size_t k = 0;
        for (; k < words.size() && !at->get_subcommands({}).empty(); ++k) {
            const std::string& w = words[k];
            if (w == "--help" || w == "-h" || (at == &app && w == "--version")) return;
            const CLI::App* next = nullptr;
            for (const auto* s : at->get_subcommands({}))
                if (s->get_name() == w) next = s;
            // The top level's commands are one --help away; a group's few are listed.
            if (!next)
                refuse("unknown command '" + w + "'" +
                       (at == &app ? "" : " (" + command_names(at) + ")"));
            at = next;
            path += " " + w;
        }
        if (!at->get_subcommands({}).empty()) refuse("needs a command: " + command_names(at));
        for (; k < words.size(); ++k) {
            const std::string& w = words[k];
            if (!names_an_option(w)) continue;
            const std::string name = w.substr(0, w.find('='));
            if (at->get_option_no_throw(name) == nullptr) refuse("unknown option " + name);
        }
    }

    // A word after the command that CLI11 would take for an option: not "-2.5" nor "-.5" (a
    // negative number is a value), nor the help it answers itself.
    static bool names_an_option(const std::string& w) {
        if (w.size() < 2 || w[0] != '-' || w == "--help" || w == "-h") return false;
        return !(std::isdigit(static_cast<unsigned char>(w[1])) || w[1] == '.');
    }

    static std::string command_names(const CLI::App* group) {
        std::string names;
        for (const auto* s : group->get_subcommands({})) {
            if (!names.empty()) names += ", ";
            names += s->get_name();
        }
        return names;
    }

    Args given_to(std::size_t k) const {
        std::map<std::string, std::string> values;
        std::set<std::string> flags;
        std::vector<std::string> positional;
        for (const auto& d : declared[k]) {
            if (d.option->count() == 0) continue;
            switch (d.given) {
                case Given::flag:
                    flags.insert(d.option->get_name());
                    break;
                case Given::optional:
                case Given::required:
                    values[d.option->get_name()] = d.option->results().front();
                    break;
                case Given::word:
                case Given::words:
                case Given::any_words:
                    positional = d.option->results();
                    break;
            }
        }
        return Args(std::move(values), std::move(flags), std::move(positional));
    }

    int run(int argc, char** argv) {
        std::vector<std::string> words(argv + 1, argv + argc);
        if (words.empty()) {
            std::cerr << app.help();
            return 2;
        }
        if (words[0] == "help") words[0] = "--help";
        check_words(words);
        std::vector<std::string> reversed(words.rbegin(), words.rend());
        try {
            app.parse(reversed);
        } catch (const CLI::CallForHelp&) {
            const Reached r = reached();
            std::cout << r.app->help(r.above);
            return 0;
        } catch (const CLI::CallForVersion& e) {
            std::cout << e.what() << "\n";
            return 0;
        } catch (const CLI::ParseError& e) {
            const std::string path = reached().path();
            throw UsageError(path.substr(7) + ": " + e.what(), path);
        }
        for (std::size_t k = 0; k < apps.size(); ++k)
            if (apps[k]->parsed()) return commands[k].run(given_to(k));
        throw std::logic_error("no command ran");
    }
};

}  // namespace

int main(int argc, char** argv) {
    // Two malloc arenas, not glibc's eight a core: every web connection is a thread of its own,
    // and each arena keeps the peak of what its threads drew (a live view, a record), so that 24
    // viewers of the live view raised a cycle's peak by 188 MiB with eight a core
    // (tests/network/web_load.py). The box's threads seldom allocate at once.
    mallopt(M_ARENA_MAX, 2);
    try {
        CommandLine command_line;
        return command_line.run(argc, argv);
    } catch (const calbox::geometry::PatternError& e) {
        calbox::board::log_to_standard_error(calbox::hal::LogLevel::error, e.what());
        return 2;
    } catch (const UsageError& e) {
        calbox::board::log_to_standard_error(
            calbox::hal::LogLevel::error,
            std::string(e.what()) + " (see " + e.help_of() + " --help)");
        return 2;
    } catch (const std::exception& e) {
        calbox::board::log_to_standard_error(calbox::hal::LogLevel::error, e.what());
        return 1;
    }
}
