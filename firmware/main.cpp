// calbox: one binary; each subcommand exposes one step of the calibration cycle.
#include <iostream>
#include <string>
#include <vector>

#include "core/geometry/pattern_spec.hpp"
#include "firmware/cli_args.hpp"

namespace {

constexpr const char* kHelp = R"(calbox: calibrates machines from photos of what they make

usage: calbox COMMAND [ARGS...]

commands:
  run                         the appliance: the one-button calibration cycle (calbox run --help)
  revert                      send the settings backed up before the last applied cycle
  camera calibrate|plane      intrinsic calibration and the bed plane (calbox camera --help)
  detect markers|chessboard|circles   what the box sees in an image (calbox detect --help)
  measure delta|galvo         measure the made target in photos (calbox measure --help)
  solve delta|galvo           fit the machine's model and write the correction (calbox solve --help)
  compensate                  a job sent through a solve's correction (calbox compensate --help)
  target delta|galvo|svg      a calibration target, or a job from a drawing (calbox target --help)
  sim print|photo             the digital twin: run a G-code job, render a photo (calbox sim --help)

Every command exits 0 on success, and non-zero with one line on standard error on failure.
)";

}  // namespace

int main(int argc, char** argv) {
    const std::vector<std::string> words(argv + 1, argv + argc);
    try {
        if (words.empty()) {
            std::cerr << kHelp;
            return 2;
        }
        if (words[0] == "--help" || words[0] == "-h" || words[0] == "help") {
            std::cout << kHelp;
            return 0;
        }
        if (words[0] == "--version") {
            std::cout << "calbox 0.1.0\n";
            return 0;
        }
        const std::vector<std::string> rest(words.begin() + 1, words.end());
        if (words[0] == "run") return calbox::cli::run_appliance(rest);
        if (words[0] == "revert") return calbox::cli::run_revert(rest);
        if (words[0] == "sim") return calbox::cli::run_sim(rest);
        if (words[0] == "camera") return calbox::cli::run_camera(rest);
        if (words[0] == "detect") return calbox::cli::run_detect(rest);
        if (words[0] == "target") return calbox::cli::run_target(rest);
        if (words[0] == "solve") return calbox::cli::run_solve(rest);
        if (words[0] == "measure") return calbox::cli::run_measure(rest);
        if (words[0] == "compensate") return calbox::cli::run_compensate(rest);
        throw calbox::cli::UsageError("unknown command '" + words[0] +
                                      "' (calbox --help lists them)");
    } catch (const calbox::geometry::PatternError& e) {
        std::cerr << "calbox: " << e.what() << "\n";
        return 2;
    } catch (const calbox::cli::UsageError& e) {
        std::cerr << "calbox: " << e.what() << " (see calbox --help)\n";
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "calbox: " << e.what() << "\n";
        return 1;
    }
}
