#pragma once
// A machine file from what a printer's owner already has: a Marlin console capture (M503's
// reply, G33's report), RepRapFirmware's config.g and config-override.g, Klipper's printer.cfg
// with its SAVE_CONFIG block. What the files cannot tell is defaulted and said so.
#include <array>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/models/delta.hpp"
#include "core/models/delta_commands.hpp"
#include "core/models/machine_file.hpp"

namespace calbox::models {

class ImportError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct ImportOptions {
    // What a capture may lack: G33's report has no rod length, and no firmware file says how
    // far out the bed is printable unless its firmware keeps it.
    std::optional<double> diagonal_rod_mm;
    std::optional<double> bed_radius_mm;
};

struct ImportedMachine {
    MachineFile machine;
    // One line each for what was read from where, and what the files could not tell (defaulted).
    std::vector<std::string> notes;
};

// The number a firmware's report prints after `key` (G33's ".Height:297.80", Marlin's "Bed X:
// 10.00"), looked for from `from` on: empty when the key is not there or no finite number
// follows it.
std::optional<double> number_after(std::string_view text, std::string_view key,
                                   std::size_t from = 0);

// The settings as each firmware states them, before they become the machine file's [delta]
// (Marlin's conventions, in gauge): what the tests compare with the folders' READMEs.
struct MarlinDeltaSettings {
    std::optional<double> rod_mm, radius_mm, height_mm, bed_radius_mm;
    std::array<double, 3> angle_trim_deg{}, rod_trim_mm{}, endstop_mm{};
    bool from_g33 = false;
};
struct MarlinCapture {
    std::optional<MarlinDeltaSettings> delta;  // from M665 or G33's report (M666's endstops in it)
    std::optional<std::array<double, 2>> steps_per_mm_xy;  // M92 X Y
    bool dual_endstops = false;  // M666 with neither M665 nor G33: a cartesian's dual endstops
};
MarlinCapture read_marlin_capture(std::string_view log);

struct RrfConfig {
    std::optional<std::string> m665, m666;  // the last of each, comments stripped
    std::optional<double> bed_radius_mm;    // M665 B
};
// The files in the order RepRapFirmware runs them (config.g, then config-override.g): a later
// M665 or M666 replaces an earlier one.
RrfConfig read_rrf_config(const std::vector<std::string>& files);

// Reads a file a printer.cfg includes (a path relative to the including file's folder): empty
// when it is not there.
using ReadIncluded = std::function<std::optional<std::string>(const std::string& path)>;
// The files a wildcard include names (`[include printers/*.cfg]`): every path matching the
// pattern (`*`, `?`, `[...]`, the including file's folder before it), in any order; Klipper reads
// them sorted, as these functions do. Without one a wildcard include is noted, not read.
using ListIncluded = std::function<std::vector<std::string>(const std::string& pattern)>;
// One point DELTA_CALIBRATE probed, as SAVE_CONFIG keeps it ([delta_calibrate] heightN and
// heightN_pos): the height the probe reported and each stepper's position, in steps below its
// tower's endstop.
struct KlipperSavedProbe {
    double height_mm = 0;
    std::array<double, 3> steps_below_endstop{};
};

struct KlipperConfig {
    KlipperDelta delta;
    std::optional<double> print_radius_mm;
    std::vector<std::string> notes;  // includes not found
    // Each stepper's full steps x microsteps / rotation_distance, where all three are given
    // (stepper_b and _c take stepper_a's where they give none).
    std::optional<std::array<double, 3>> steps_per_mm;
    std::vector<KlipperSavedProbe> saved_probe;  // heightN in order, empty without them
};
// printer.cfg's sections merged as Klipper reads them: includes in place (those not found noted
// in `notes`), later values over earlier, the SAVE_CONFIG block (#*# lines) over everything.
// Throws ImportError for an include loop.
using KlipperSections = std::map<std::string, std::map<std::string, std::string>>;
KlipperSections read_klipper_sections(const std::string& path, const std::string& text,
                                      const ReadIncluded& read, std::vector<std::string>& notes,
                                      const ListIncluded& list = {});
// The delta's settings in those sections. Throws ImportError as above, and for a printer that is
// not a delta, missing keys or a malformed value.
KlipperConfig read_klipper_config(const std::string& path, const std::string& text,
                                  const ReadIncluded& read, const ListIncluded& list = {});

ImportedMachine import_marlin(std::string_view log, const ImportOptions& options);
ImportedMachine import_rrf(const std::vector<std::string>& files, const ImportOptions& options);
ImportedMachine import_klipper(const std::string& path, const std::string& text,
                               const ReadIncluded& read, const ImportOptions& options,
                               const ListIncluded& list = {});

// The machine file as TOML, the notes as its opening comments.
std::string machine_file_text(const ImportedMachine& imported);

}  // namespace calbox::models
