// calbox machine import
#include <glob.h>

#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/models/machine_import.hpp"
#include "firmware/cli/cli_args.hpp"

namespace calbox::cli {
namespace {

// The files a wildcard include names (Klipper's glob), in the order glob gives them; the import
// sorts them as Klipper does.
std::vector<std::string> matching_files(const std::string& pattern) {
    glob_t found{};
    std::vector<std::string> paths;
    if (::glob(pattern.c_str(), GLOB_NOSORT, nullptr, &found) == 0)
        paths.assign(found.gl_pathv, found.gl_pathv + found.gl_pathc);
    ::globfree(&found);
    return paths;
}

// An included file Klipper's config names: empty where it is not there (said, not fatal).
std::optional<std::string> read_if_there(const std::string& path) {
    try {
        return read_input_file(path, "included file");
    } catch (const std::runtime_error&) {
        return std::nullopt;
    }
}

// The machine the one source given describes (--marlin, --klipper or --rrf's files); throws
// models::ImportError naming what it could not read.
models::ImportedMachine imported_machine(const Args& args, const models::ImportOptions& options) {
    if (const auto log = args.get("--marlin"))
        return models::import_marlin(read_input_file(*log, "console capture"), options);
    if (const auto cfg = args.get("--klipper"))
        return models::import_klipper(*cfg, read_input_file(*cfg, "printer.cfg"), read_if_there,
                                      options, matching_files);
    if (args.positional().empty()) throw UsageError("--rrf needs config.g (and config-override.g)");
    std::vector<std::string> files;
    for (const auto& path : args.positional())
        files.push_back(read_input_file(path, "RepRapFirmware configuration"));
    return models::import_rrf(files, options);
}

int import_machine(const Args& args) {
    const std::string out = args.require("-o");
    models::ImportOptions options;
    if (args.get("--diagonal-rod")) options.diagonal_rod_mm = args.number("--diagonal-rod", 0);
    if (args.get("--bed-radius")) options.bed_radius_mm = args.number("--bed-radius", 0);
    const int sources = (args.get("--marlin") ? 1 : 0) + (args.get("--klipper") ? 1 : 0) +
                        (args.flag("--rrf") ? 1 : 0);
    if (sources != 1) throw UsageError("machine import takes one of --marlin, --rrf, --klipper");
    if (!args.flag("--rrf") && !args.positional().empty())
        throw UsageError("machine import: '" + args.positional().front() +
                         "' is a file for --rrf alone");
    // Every refusal names the input it comes from, never the file being written.
    const std::string input = args.get("--marlin")        ? *args.get("--marlin")
                              : args.get("--klipper")     ? *args.get("--klipper")
                              : args.positional().empty() ? std::string("config.g")
                                                          : args.positional().front();
    models::ImportedMachine imported;
    try {
        imported = imported_machine(args, options);
    } catch (const models::ImportError& e) {
        const std::string why = e.what();
        throw std::runtime_error(why.rfind(input, 0) == 0 ? why : input + ": " + why);
    }
    const std::string text = models::machine_file_text(imported);
    // What is written must read back as a machine file; where it does not, the input's figure
    // is at fault (a negative radius), and the message names the input.
    try {
        models::parse_machine_file(text, input + " (as imported)");
    } catch (const models::MachineFileError& e) {
        throw std::runtime_error(e.what());
    }
    write_output_file(out, text);
    for (const auto& note : imported.notes) std::printf("%s\n", note.c_str());
    std::printf("%s: a %s printer (%s)\n", out.c_str(), imported.machine.kind.c_str(),
                imported.machine.firmware.c_str());
    return 0;
}

}  // namespace

std::vector<Command> machine_commands() {
    return {{"machine import",
             "a machine file from the printer's own files",
             {{"--marlin", "LOG", "a Marlin console capture (M503's reply, or G33's report)"},
              {"--rrf", "", "RepRapFirmware: CONFIG files follow", Given::flag},
              {"CONFIG", "", "with --rrf: config.g, then config-override.g", Given::any_words},
              {"--klipper", "printer.cfg", "Klipper's configuration, with its includes"},
              {"--diagonal-rod", "MM", "the rod length, where the files leave it out"},
              {"--bed-radius", "MM", "the printable radius, where the files leave it out"},
              {"-o", "machine.toml", "the machine file, written", Given::required}},
             R"(A machine file from the printer's own files, its geometry as the firmware holds it:
--marlin: a console capture from any host (M503's reply: M665, M666, M92; or G33's
report, which leaves out the rod: give --diagonal-rod); --rrf: config.g then
config-override.g (a later M665 or M666 replaces an earlier one); --klipper: printer.cfg
with its includes (wildcards too, in sorted order) and its SAVE_CONFIG block over the
sections above it, as Klipper reads it. What the files cannot tell (the printable
radius, the bed's material, the line width) is defaulted and said so, on standard
output and at the file's top. A capture without a delta's geometry but with M92 gives a
cartesian printer.)",
             import_machine}};
}

}  // namespace calbox::cli
