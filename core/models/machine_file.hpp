#pragma once
// The machine file (TOML), shared by every mode: [machine] with the kind, firmware, work area,
// extrusion or tool settings and temperatures, then one table per kind holding what the
// machine's firmware believes now ([delta] for a delta printer).
#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "core/models/machine_kinds.hpp"

namespace calbox::models {

class MachineFileError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// [delta]: the firmware's geometry in Marlin's conventions.
struct DeltaSettings {
    double diagonal_rod_mm = 250.0;
    std::array<double, 3> diagonal_rod_trim_mm{0, 0, 0};  // towers A B C
    double radius_mm = 140.0;
    std::array<double, 3> tower_angle_trim_deg{0, 0, 0};  // towers at 210, 330, 90 degrees
    std::array<double, 3> endstop_offset_mm{0, 0, 0};     // M666, <= 0
    double height_mm = 300.0;
};

// [galvo]: the scanner's field as its controller addresses it, in scanner millimetres centred
// on the field's middle, and the height of the surface it marks.
struct GalvoSettings {
    double field_size_mm = 110.0;  // the square field's side
    // The marked surface (powder layer, Zp) above the plane the bed-plane board lay on: the
    // camera maps marks at this height.
    double substrate_height_mm = 0.0;
    // How a burn shows on the substrate: "dark" on a light one (paper, anodised aluminium's
    // white oxide, powder), "light" where the laser bleaches or foams it (dark anodising).
    std::string marks = "dark";
};

// [planar]: routers, cartesian printers and gantry lasers calibrated from a grid of holes or
// dots over the work area.
struct PlanarSettings {
    double hole_pitch_mm = 25.0;  // the grid's pitch
    // The outer holes' centres lie at least this far inside the work area.
    double margin_mm = 15.0;
    // The marked surface (the sheet's top) above the plane the bed-plane board lay on: the
    // camera maps the holes at this height.
    double surface_height_mm = 0.0;
    // The tool point below the guides the carriage runs on (the seed's X3): the lever over
    // which pitch and roll move the tool. Only the held parameters' report depends on it.
    double tool_length_mm = 60.0;
    double plunge_feed_mm_s = 5.0;  // routers: drilling feed
    double dwell_s = 0.3;           // routers: at the bottom of each hole, so it is round
    // The firmware's steps per mm now (Marlin M92, grbl $100 / $101): given, the result says
    // the new values; not given, the factor to multiply them by.
    std::optional<double> steps_per_mm_x, steps_per_mm_y;
    // How a hole or mark shows on the sheet: "dark" (a drilled hole over a dark backing, a
    // burned dot on a light sheet: the default for routers and lasers) or "light" (a light
    // filament's dots on a dark printing sheet: the default for cartesian printers; a light
    // backing under a dark sheet).
    std::string holes = "dark";
};

// [probe]: a delta printer's own bed probe, which the box has probe the bed over the machine
// link before it prints the target (Marlin's G30, RepRapFirmware's G30 S-1): the probed gap
// makes one pass enough. Its points: the centre, rings at half the radius and at the radius.
struct ProbeSettings {
    double radius_mm = 0;            // within the probe's reach on the bed
    double repeatability_mm = 0.01;  // one reading's standard uncertainty
};

// [touch_probe]: a router's touch probe on grbl's probe input (a plate or a probe at the
// spindle), which the box may use to measure the stock's top above the bed (the console's
// `probe stock`): grbl's G38.2 straight down on the sheet and beside it, the two [PRB] heights'
// difference. Before moving over the bed the tool is lifted to `clear_z_mm` in machine
// coordinates (G53): a height above anything on the bed, which the box cannot see.
struct TouchProbeSettings {
    double clear_z_mm = 0;           // machine Z, required
    double travel_mm = 25;           // how far down each probe may go before grbl's alarm 5
    double feed_mm_min = 60;         // G38.2's feed
    double repeatability_mm = 0.01;  // one touch's standard uncertainty
};

// What a delta correction may change before it is refused, never sent (the machine file's
// [limits]: a tighter bound for a machine known to be close, a wider one for a rebuilt one).
struct DeltaLimits {
    double max_rod_change_fraction = 0.02;  // the fit's and the classic method's
    double max_angle_trim_deg = 3.0;
    double max_radius_change_fraction = 0.02;
    // The residual against the measurements' own uncertainty: beyond this the points are not a
    // delta printer's work (a wrong match, a loose part, a bad photo) and nothing is corrected.
    double max_residual_ratio = 3.0;
};

// [link]: how the box reaches the machine. "serial": the port its board gives it, which it
// owns. "moonraker": Klipper through its Moonraker host at `url`, which owns the printer's port;
// "octoprint": Marlin through OctoPrint; "duet": RepRapFirmware through a Duet's web API (its
// key_file holds the board's password); "linuxcnc": LinuxCNC through its linuxcncrsh server at
// `url` HOST:PORT (its key_file holds the connect and the enable password).
struct MachineLinkSettings {
    std::string kind = "serial";  // one of core/models/link_kinds.hpp's
    // A host's: "http://printer.local:7125" (the sim board's own); linuxcnc's "cnc.local:5007".
    std::string url;
    // A file holding the host's API key: the key itself is never in the machine file, which is
    // copied into records and shown.
    std::string key_file;
    // An https host's certificate authority, a PEM file, for a host whose certificate it signed
    // itself (empty: the system's authorities).
    std::string ca_file;
    double reply_timeout_s = 30;    // a command's reply, a file's transfer
    double restart_timeout_s = 60;  // a firmware restart until the printer is ready again
    bool is_host() const;           // reached over the network (link_kinds.hpp)
};

struct MachineFile {
    std::string kind = "delta";  // a name in core/models/machine_kinds.hpp
    std::string firmware = "marlin";
    double bed_radius_mm = 85;   // delta: the printable radius around the origin
    double bed_size_x_mm = 200;  // others: the work area from the origin
    double bed_size_y_mm = 200;
    // Planar machines: the machine's XY travel in machine coordinates (a job point beyond it is
    // refused), by default the work area from the origin; and the machine coordinates of the
    // work zero in force while the box's target runs (grbl's G54), by default the origin.
    std::optional<double> travel_min_x_mm, travel_max_x_mm, travel_min_y_mm, travel_max_y_mm;
    std::optional<double> work_zero_x_mm, work_zero_y_mm;
    double line_width_mm = 0.45;              // printers
    double layer_height_mm = 0.2;             // printers
    double filament_diameter_mm = 1.75;       // printers
    double tool_width_mm = 0.1;               // laser spot or cutter width
    double feed_mm_s = 20;                    // working moves
    double travel_feed_mm_s = 100;            // moves with the tool off
    double laser_power = 1.0;                 // fraction of full power (laser, galvo)
    double spindle_rpm = 10000;               // router
    double cut_depth_mm = 0.5;                // router: depth of the cut below the surface
    double safe_height_mm = 5;                // router and printer travel height
    std::optional<std::string> bed_material;  // aluminium | glass | steel | fr4
    std::optional<double> bed_temperature_c;  // while printing
    // The bed when the box photographs the print (it waits for it to cool there); a reading
    // given to measure overrides it. Not given: photographed as printed.
    std::optional<double> photo_bed_temperature_c;
    std::optional<double> nozzle_temperature_c;
    std::optional<std::string> start_gcode;  // printers: replaces heating and G28 at a job's start
    std::optional<std::string> end_gcode;    // printers: replaces cooling and M84 at its end
    std::optional<DeltaSettings> delta;
    std::optional<GalvoSettings> galvo;
    std::optional<PlanarSettings> planar;  // every router, cartesian and laser machine
    std::optional<ProbeSettings> probe;    // a delta printer's own probe, when the box may use it
    std::optional<TouchProbeSettings> touch_probe;  // a router's, on grbl
    DeltaLimits delta_limits;                       // [limits]: a delta's
    MachineLinkSettings link;                       // [link]

    // The row of `kind` in core/models/machine_kinds.hpp, which every answer below reads; a
    // kind the table does not hold is refused (std::invalid_argument), never taken for another.
    const MachineKind& kind_row() const;
    MachineFamily family() const { return kind_row().family; }
    MachineTool tool() const { return kind_row().tool; }
    bool is_printer() const { return kind_row().printer; }
    bool is_delta() const { return family() == MachineFamily::delta; }
    bool is_galvo() const { return family() == MachineFamily::galvo; }
    bool is_planar() const { return family() == MachineFamily::planar; }
    bool jobs_at_work_zero() const { return kind_row().jobs_at_work_zero; }
};

// A planar machine's travel in machine coordinates: [min x, min y, max x, max y].
std::array<double, 4> planar_travel_mm(const MachineFile& machine);

// The bed plate is fixed at its centre and grows with temperature; a print sticks to it and
// goes along. Linear expansion per kelvin of a bed material; throws MachineFileError.
double bed_expansion_per_k(const std::string& material);
// How much larger everything on the bed is in a photo taken with the bed at
// `photo_bed_temperature_c` (else the machine file's) than when it was printed at
// bed_temperature_c: 1 when neither gives a photo temperature (photographed as printed). Throws
// MachineFileError when a photo temperature is given but the machine file lacks the bed's material
// or print temperature.
double bed_scale_at_photo(const MachineFile& machine,
                          std::optional<double> photo_bed_temperature_c);

// A short digest of everything the machine file says (its parsed values, so formatting and
// comments do not count): measurements carry it, and solving them against another machine is
// refused.
std::string fingerprint(const MachineFile& machine);
// The same kind of digest of any canonical text ("fnv1a64:" and 16 hex digits).
std::string digest(std::string_view canonical);

// Why `machine`'s link cannot reach its firmware ("" when it can): Moonraker serves Klipper,
// OctoPrint Marlin. The machine file's [link] is checked so, and so is one the box's
// configuration overrides.
std::string link_mismatch(const MachineFile& machine);

// Parses a whole machine file; `source` names it in messages. Unknown sections and keys are
// errors, except sections listed in `other_sections` (a twin scenario adds its own).
MachineFile parse_machine_file(std::string_view toml_text, const std::string& source,
                               std::initializer_list<std::string_view> other_sections = {});

}  // namespace calbox::models
