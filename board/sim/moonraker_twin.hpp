#pragma once
// The twin Klipper printer behind its Moonraker host, on loopback: the same twin bench as over
// the pty, reached through Moonraker's API (its websocket's JSON-RPC, its file upload and
// download), with its API key. printer.cfg lives in a directory of the host's own, kept from one
// run to the next as the host's disk keeps it, and is read (by the twin's own reader: it does not
// share the box's) at each FIRMWARE_RESTART. A delta's geometry or a cartesian printer's travel
// and skew (SET_SKEW, SKEW_PROFILE and SAVE_CONFIG, which writes printer.cfg as Klipper does).
// Faults from the scenario's [faults] make it misbehave as real hosts do.
#include <filesystem>
#include <memory>
#include <string>

#include "board/sim/delta_reference.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/twin_host.hpp"

namespace calbox::sim {

// The twin's own reading of a Klipper delta's printer.cfg: sections, then the SAVE_CONFIG block
// over them; stepper_b and _c take stepper_a's arm_length and position_endstop when they give
// none, the angles default to 210, 330 and 90. Throws std::runtime_error as Klipper refuses a
// config ("Option 'delta_radius' in section 'printer' must be specified").
DeltaParams twin_params_from_printer_cfg(const std::string& text);
// Its [probe] z_offset (0 without one): its PROBE reports the toolhead's height at the trigger.
double twin_probe_z_offset(const std::string& text);
// A printer.cfg for a twin delta (as its owner would have written it), with a probe.
std::string printer_cfg_of(const DeltaParams& firmware, double print_radius_mm);

// A cartesian Klipper printer's: each axis's travel per commanded mm from its rotation_distance
// (against kOwnersRotationDistanceMm, the value its owner's file had, which the truth's scale
// errors are measured with); no skew in force (Klipper loads a profile only when told). Throws
// std::runtime_error as Klipper refuses a config.
constexpr double kOwnersRotationDistanceMm = 40;
CartesianFirmware twin_cartesian_from_printer_cfg(const std::string& text);
std::string printer_cfg_of_cartesian(double bed_size_x_mm, double bed_size_y_mm);
// Klipper's skew_correction from a printed square's AC, BD and AD (its calc_skew_factor).
double twin_skew_factor(double ac_mm, double bd_mm, double ad_mm);

class MoonrakerTwin final : public TwinHostServer {
  public:
    // Serves on 127.0.0.1, a free port. `host_dir` holds printer.cfg (written from the bench's
    // printer when absent) and the uploaded jobs.
    MoonrakerTwin(std::shared_ptr<TwinBench> bench, std::filesystem::path host_dir,
                  TwinHostSettings settings);
    MoonrakerTwin(const MoonrakerTwin&) = delete;
    MoonrakerTwin& operator=(const MoonrakerTwin&) = delete;
    ~MoonrakerTwin() override;
    std::string url() const override;
    // Websocket connections opened with a one-shot token (GET /access/oneshot_token).
    int tokens_redeemed() const;

  private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace calbox::sim
