// calbox: one binary; each subcommand exposes one step of the calibration cycle.
#include <iostream>
#include <string>
#include <vector>

#include "core/geometry/pattern_spec.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/version.hpp"

namespace {

using calbox::cli::UsageError;

struct Subcommand {
    const char* name;
    const char* usage;  // what follows the name in the list
    const char* help;
    int (*run)(const std::vector<std::string>& words);
};

// The modes, as `target`, `measure` and `solve` name them.
constexpr const char* kModes = "delta|galvo|planar";

// One row a subcommand: `calbox --help` lists them and `calbox NAME` runs one.
const Subcommand kSubcommands[] = {
    {"run", "", "the appliance: the one-button calibration cycle", calbox::cli::run_appliance},
    {"revert", "", "put back what the last applied cycle changed", calbox::cli::run_revert},
    {"camera", "calibrate|plane", "intrinsic calibration and the bed plane",
     calbox::cli::run_camera},
    {"detect", "markers|chessboard|circles", "what the box sees in an image",
     calbox::cli::run_detect},
    {"target", "MODE|svg", "a calibration target, or a job from a drawing",
     calbox::cli::run_target},
    {"measure", "MODE", "measure the made target in photos", calbox::cli::run_measure},
    {"solve", "MODE", "fit the machine's model and write the correction", calbox::cli::run_solve},
    {"compensate", "", "a job sent through a solve's correction", calbox::cli::run_compensate},
    {"machine", "import", "a machine file from the printer's own files", calbox::cli::run_machine},
    {"sim", "print|photo|measurements|camera|verify", "the digital twin", calbox::cli::run_sim},
};

std::string help_text() {
    std::string out =
        "calbox: calibrates machines from photos of what they make\n\n"
        "usage: calbox COMMAND [ARGS...]   (calbox COMMAND --help for each)\n\n"
        "commands:\n";
    for (const auto& c : kSubcommands) {
        std::string usage = c.usage;
        if (const auto at = usage.find("MODE"); at != std::string::npos)
            usage.replace(at, 4, kModes);
        std::string left = std::string("  ") + c.name + (usage.empty() ? "" : " " + usage);
        left.resize(std::max<std::size_t>(left.size() + 2, 40), ' ');
        out += left + c.help + "\n";
    }
    out +=
        "\nmodes: delta (delta 3D printers), galvo (galvo laser scanners), planar (CNC routers,\n"
        "cartesian printers and gantry lasers)\n\n"
        "Every command exits 0 on success, and non-zero with one line on standard error on "
        "failure.\n";
    return out;
}

}  // namespace

int main(int argc, char** argv) {
    const std::vector<std::string> words(argv + 1, argv + argc);
    try {
        if (words.empty()) {
            std::cerr << help_text();
            return 2;
        }
        if (words[0] == "--help" || words[0] == "-h" || words[0] == "help") {
            std::cout << help_text();
            return 0;
        }
        if (words[0] == "--version") {
            std::cout << "calbox " << calbox::build_version() << "\n";
            return 0;
        }
        const std::vector<std::string> rest(words.begin() + 1, words.end());
        for (const auto& c : kSubcommands)
            if (words[0] == c.name) return c.run(rest);
        throw UsageError("unknown command '" + words[0] + "'");
    } catch (const calbox::geometry::PatternError& e) {
        std::cerr << "calbox: " << e.what() << "\n";
        return 2;
    } catch (const UsageError& e) {
        std::cerr << "calbox: " << e.what() << " (see calbox --help)\n";
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "calbox: " << e.what() << "\n";
        return 1;
    }
}
