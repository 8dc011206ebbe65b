#pragma once
// A twin scenario (TOML): a machine file (the machine as its firmware believes it), plus the
// hidden truth, the camera, and the photo's lighting and noise.
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "board/sim/camera_reference.hpp"
#include "board/sim/delta_reference.hpp"
#include "board/sim/galvo_twin.hpp"
#include "board/sim/gcode_runner.hpp"
#include "board/sim/machine_twin.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/router_twin.hpp"
#include "board/sim/scenes.hpp"
#include "board/sim/twin_host.hpp"
#include "core/models/machine_file.hpp"

namespace calbox::sim {

class ScenarioError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct ScenarioCamera {
    CameraIntrinsics intrinsics;
    Vec3 position_mm{0, 0, 400};
    Vec3 look_at_mm{0, 0, 0};
    double roll_deg = 0;
};

// [faults]: what can go wrong between the box and a real machine, injected on purpose. Zero is
// off; lines count what the printer received, from 1 after the link opened.
struct ScenarioFaults {
    int silent_after_lines = 0;       // the printer stops answering after this many lines
    int error_at_line = 0;            // it answers this line with a fatal "Error:" (halted)
    double line_noise = 0;            // chance that a received line arrives with a flipped bit
    int reset_at_line = 0;            // it resets on this line (the start-up banner follows)
    int camera_fails_at_capture = 0;  // the camera's n-th capture fails
    // The camera's n-th capture request does not return for camera_hang_s: a driver call that
    // hangs, holding up the box's event loop (what the service manager's watchdog is for).
    int camera_hangs_at_capture = 0;
    double camera_hang_s = 0;
    bool settings_ignored = false;  // M665 / M666 answered ok but not applied
    HostFaults host;                // host_*: a printer behind a host ([link])
};

// [setup]: the boards the person at the box uses to set it up (a real box's configuration says
// the same): one held in front of the camera for its calibration, one laid on the bed.
struct ScenarioSetup {
    std::string calibration_pattern = "chessboard:11x8@20";
    std::string plane_pattern = "chessboard:9x6@20";
    Vec2 plane_board_at_mm{-80, 50};                       // its first inner corner, on the bed
    Surroundings board_surroundings = Surroundings::grey;  // around the boards' paper
    // Fixed reference marks stuck on the bed outside the work area, ids 0, 1, ... of the
    // dictionary, each a white square sticker two cells wider than its marker on every side.
    // Not given: one near each corner of the camera's view (reference_marks_near_view_corners).
    bool reference_marks = true;
    std::vector<Vec2> reference_marks_at_mm;  // centres
    double reference_mark_mm = 12;
    std::string reference_dictionary = "DICT_APRILTAG_36h11";
};

// [placement]: after the cycle, a sheet of stock laid on the spoilboard where the box does not
// know it (the twin's truth, in the bed's frame: the work frame the router's errors are in); the
// box photographs it, finds its corner and places a drilling job there (`calbox run --auto`
// judges where the holes land on the sheet against goal_mm).
// Print and cut: a card printed with a drawing's cut line (the job's own path) and its
// registration marks, laid turned and shifted where the box does not know it, the printer's
// stretch on it; the box finds the marks, places the job by them and the judge says how far the
// tool really went from the printed line.
struct PrintedCard {
    Vec2 origin_mm;  // where the drawing's (0, 0) lies on the bed
    double angle_deg = 0;
    // The printer's stretch along the drawing's x and y: a paper feed stretches one way more
    // than the other, which a fit of turn, shift and one scale leaves in its residuals.
    double stretch_x = 1, stretch_y = 1;
    std::vector<Vec2> marks_mm;  // filled circles, their centres in the drawing's frame
    double mark_diameter_mm = 5;
    double card_albedo = 0.85, ink_albedo = 0.08;
    // The printed cut line: the job's own path (the X Y of its G0 and G1 lines, in order, read
    // by the twin when the scenario is loaded), in the drawing's frame.
    std::vector<Vec2> line_mm;
    // Where a drawing's point is on the bed.
    Vec2 on_bed(Vec2 drawing_mm) const;
};

struct ScenarioPlacement {
    std::optional<PrintedCard> card;  // print and cut; otherwise the sheet's corner places the job
    StockSheet sheet;
    double thickness_mm = 1.5;
    std::string job_path;  // the job, its path as given (relative to the scenario's)
    std::string corner = "nearest";
    double goal_mm = 0.1;
    // The sheet or the card already lies on the bed when the box starts (a box started to place
    // a job, with its correction kept from an earlier run): the camera sees it until a board is
    // held.
    bool on_bed_at_start = false;
};

struct Scenario {
    std::string path;
    models::MachineFile machine;      // the machine-file keys: [machine] and [delta]
    DeltaParams delta_firmware;       // [delta]
    DeltaParams delta_truth;          // [truth.delta]: keys not given equal the firmware's
    CartesianErrors cartesian_truth;  // [truth.cartesian]
    GalvoTruth galvo_truth;           // [truth.galvo]: a seeded scanner, keys given override
    RouterTruth router_truth;         // [truth.router]: a seeded router, keys given override
    bool zero_height_at_centre = true;
    // [twin] levelled_by: how the printer's bed was levelled before the box saw it. "centre":
    // only the height zeroed at the centre; "paper": an owner's paper test at the towers and the
    // centre (DeltaTwin::level_by_paper at 0.8 of the bed's radius); "probe": a probe routine
    // (level_by_probe over 0.9 of it). Implies zero_height_at_centre.
    std::string levelled_by = "centre";
    double segment_mm = 0.5;
    // [twin] host_print_seconds: a print on a twin host lasts at least this long (a real one
    // takes minutes; the twin's runs at once unless told).
    double host_print_seconds = 0;
    // [twin] duet_sbc: the twin Duet has an SBC (DuetSoftwareFramework's /machine API, no rr_).
    bool duet_sbc = false;
    // [twin] host_tls: the twin host serves https (and wss) behind a TLS terminator, with a
    // certificate of its own making the box is given to trust (DATA/twin-host-ca.pem).
    bool host_tls = false;
    bool real_first_layer = true;  // [twin] first_layer = "real" (default) | "as_commanded"
    std::optional<ScenarioCamera> camera;
    PhotoSettings photo;
    std::optional<double> photo_bed_temperature_c;  // [photo]: the bed when photographed
    double bed_albedo = 0.08;                       // matte black PEI
    double material_albedo = 0.85;                  // white PETG
    StrokeSurface surface;                          // [photo]: the bed's grain, the gloss
    // [photo]: the box's lamp as the glossy things in view mirror it (glare_of_surface's names):
    // the board laid or held in front of the camera, and the bed or plate with the work on it.
    // glare_strength scales both surfaces' peaks (0 turns the lamp's reflection off).
    std::string board_surface = "matte";
    std::string bed_surface = "matte";
    double glare_strength = 1;
    Vec3 lamp_from_camera_mm{60, 0, 0};
    // [photo] exposure_us: the exposure at which a white surface gives exposure_dn; a capture
    // asking for another scales the light by the ratio.
    double nominal_exposure_us = 10000;
    ScenarioFaults faults;
    ScenarioSetup setup;
    std::optional<ScenarioPlacement> placement;
};

// The scenario's photo settings with the box's lamp mirrored by the board (a board in view) or
// by the bed or plate.
enum class InView { board, bed };
PhotoSettings photo_settings_of(const Scenario& s, InView what);

// A bound on how far a camera pixel's footprint reaches on the bed, for the stroke index: three
// pixels at the camera's distance (scenes.hpp), 1 mm without a camera.
double stroke_footprint_mm(const Scenario& s);

// The same delta geometry in the twin's own struct and in the machine file's keys.
DeltaParams twin_params(const models::DeltaSettings& d);
models::DeltaSettings machine_settings(const DeltaParams& p);

// The bed plate, fixed at its centre, grows with temperature and carries the print stuck on it:
// how much larger the print is in the photo than where the nozzle laid it (1 without a photo
// temperature). Throws ScenarioError when the machine lacks the bed's material or temperature.
double bed_growth_at_photo(const Scenario& s);
std::vector<StrokeSegment> carried_by_bed(std::vector<StrokeSegment> strokes, double growth);
// What the camera sees of the material a job laid down: carried by the bed's growth, and a
// router's cuts on the sheet's top (the dark backing shows through the holes).
std::vector<StrokeSegment> as_photographed(const Scenario& s, std::vector<StrokeSegment> strokes);

// The material a stroke left, as the camera sees it: its top at the height the strand has.
StrokeSegment material_of(const Stroke& s);

// Throws ScenarioError naming the file and the key at fault.
Scenario load_scenario(const std::string& path);

std::unique_ptr<MachineTwin> make_machine_twin(const Scenario& s);

// The judge of a router, cartesian printer or laser scenario, in its truth: a fresh job half a
// pitch off the target's grid, as commanded and (with `correct`) through the correction.
RouterVerdict judge_planar_machine(const Scenario& s, const jobs::Correction* correct);
ToolSettings tool_settings_of(const Scenario& s);

}  // namespace calbox::sim
