#pragma once
// Klipper's printer.cfg as the box writes it and reads it back: values put where SAVE_CONFIG
// keeps them, and a cartesian printer's travel and skew settings (a planar fit's linear part).
#include <optional>
#include <string>
#include <vector>

namespace calbox::models {

struct KlipperSavedValue {
    std::string section, key, value;
};
// printer.cfg with `values` where Klipper's SAVE_CONFIG keeps what it saves: the "#*#" block at
// its end, which Klipper reads over the sections above. The block's other values and everything
// above it stay as they are; a file without the block gets one, as SAVE_CONFIG would write it.
// Throws std::invalid_argument for a block that is not SAVE_CONFIG's.
std::string klipper_saved_values(const std::string& printer_cfg,
                                 const std::vector<KlipperSavedValue>& values);

// The probe's z_offset (its trigger's height above the bed with the nozzle touching it) from
// printer.cfg or the settings in force: [probe], else [bltouch]; empty without either. Throws
// ImportError for a value that is not a number.
std::optional<double> klipper_probe_z_offset(const std::string& source, const std::string& text);

// The skew profile the box saves and loads (SKEW_PROFILE SAVE=calbox).
constexpr const char* kKlipperSkewProfile = "calbox";

// A cartesian Klipper printer's settings that carry the linear part of its error: each axis's
// rotation_distance (mm of travel per motor turn: an axis that travels (1 + s) too far needs
// (1 + s) times it), and the box's skew profile (Klipper's xy_skew: x moved by -xy_skew per mm of
// y before the kinematics), if saved.
struct KlipperCartesian {
    double rotation_distance_x_mm = 0, rotation_distance_y_mm = 0;
    std::optional<double> xy_skew;
    bool takes_skew = false;  // printer.cfg has a [skew_correction] section: SET_SKEW exists
};
// From printer.cfg, or from Klipper's settings in force written as one. Throws ImportError (one
// line naming `source`) for a printer that is not cartesian, or a value missing or malformed.
KlipperCartesian read_klipper_cartesian(const std::string& source, const std::string& text);

// The settings that leave a printer with `now`'s settings (its skew profile loaded) square and
// true, when it was measured with `scale_x`, `scale_y` and `skew` (planar_firmware_settings: x
// travelling (1 + scale_x) times what is commanded, y (1 + scale_y), x moving `skew` per mm of
// commanded y).
KlipperCartesian klipper_cartesian_corrected(const KlipperCartesian& now, double scale_x,
                                             double scale_y, double skew);
// The commands that save `xy_skew` as the box's profile, as Klipper's skew calibration takes a
// printed square's measurements: the diagonals AC and BD and the side AD of a 100 mm square made
// by a printer that leans so (SET_SKEW XY=AC,BD,AD), then SKEW_PROFILE SAVE.
std::vector<std::string> klipper_skew_commands(double xy_skew);
// printer.cfg's SAVE_CONFIG values for the rotation distances.
std::vector<KlipperSavedValue> klipper_travel_values(const KlipperCartesian& k);
// Whether printer.cfg `now` holds `before`'s settings but for what the box sets on a cartesian
// printer (the rotation distances, its skew profile): the file as the box's apply left it,
// however far it got, and not someone else's: the lines above the SAVE_CONFIG block as they were
// (SAVE_CONFIG may have commented out those its block sets), the settings the same.
bool klipper_changed_only_travel_and_skew(const std::string& before, const std::string& now);
// The settings sent against the ones Klipper took: empty when they agree to what was sent
// (rotation distances to 6 decimals, the skew to 1e-6), else one line naming the first difference.
std::string klipper_cartesian_mismatch(const KlipperCartesian& sent,
                                       const KlipperCartesian& in_force);

}  // namespace calbox::models
