#pragma once
// The planar mode (routers, cartesian printers, gantry lasers): a photo of the drilled (or
// printed, or marked) hole grid -> where each hole was made, indexed on the grid whatever way
// round the photo shows it; the quasi-static error model fitted to it; compensated jobs and
// the firmware's own settings; the mode's files. The command line and `calbox run` call these.
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/models/machine_file.hpp"
#include "core/models/planar_errors.hpp"
#include "core/modes/record_error.hpp"
#include "core/targets/planar_target.hpp"
#include "core/vision/spots.hpp"

namespace calbox::modes {

class PlanarError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct PlanarMeasureSettings {
    targets::PlanarTargetOptions target;  // the design the sheet was drilled with
    vision::SpotSettings spots;
    // A hole is looked for this far (in pitches) from where the fiducials predict it: the
    // errors being measured (a few millimetres at the far corners of a badly set machine, and
    // the turn the fiducials' own corner has against the rest) stay inside it; the next hole,
    // a pitch away, stays outside.
    double match_reach_pitch = 0.4;
    // A hole whose second moments are more elongated than this has a chip or a burr on its edge
    // (a clean drilled hole seen through the lens is round to a percent or two).
    double max_elongation = 1.08;
    // Holes of one kind are drilled alike: one whose equivalent radius is this fraction off its
    // kind's median has a chip, a burr or swarf in it.
    double max_radius_deviation = 0.05;
};

struct PlanarHoleMeasurement {
    targets::GridIndex index;
    geometry::Point2 commanded_mm;  // machine coordinates
    bool large = false;
    geometry::Point2 measured_mm;  // bed frame (right-handed as the machine's), surface height
    double sigma_mm = 0;           // standard uncertainty of each coordinate
};

struct PlanarMeasurement {
    std::string machine_fingerprint, target_fingerprint;
    std::vector<std::string> photos;
    int columns = 0, rows = 0;
    double pitch_mm = 0;
    // The photo's bed frame was mirrored against the machine's (y flipped back in measured_mm).
    bool mirrored = false;
    std::vector<PlanarHoleMeasurement> holes;
    // The router's hole drilled from the other side (targets::PlanarTarget::backlash_hole).
    std::optional<PlanarHoleMeasurement> backlash_hole;
    std::vector<targets::GridIndex> missing;  // holes the job made that were not measured
    std::vector<geometry::Point2> extra_mm;   // blobs that are no hole of the grid (chips, swarf)
};

// A short job: the `holes` grid nodes (of the machine's full target, fiducials aside) that
// DETMAX finds best for the model, as node indices (row * columns + column) for
// PlanarTargetOptions::only_nodes. The same machine and count always give the same design.
std::vector<std::size_t> planar_design_nodes(const models::MachineFile& machine, std::size_t holes);

// Throws PlanarError with one line when the photo cannot be indexed (no fiducials, not this
// grid, part of it outside the photo, holes where the grid has none).
PlanarMeasurement measure_planar(const models::MachineFile& machine,
                                 const geometry::CameraModel& camera,
                                 const geometry::BedPlane& plane, const vision::GrayView& photo,
                                 const PlanarMeasureSettings& settings = {});

// A sheet larger than one view, photographed by a camera the machine carries (on its gantry):
// each photo with the machine position the camera was sent to. The first photo shows the two
// large holes; `plane` is the bed plane seen from there. The offsets only say which hole is
// which (they carry the machine's own errors); where the holes are comes from the photos,
// stitched through the holes they share (each photo's rotation and shift fitted so that a hole
// seen twice is seen at one place). Throws PlanarError when a photo shares under 3 holes with
// the others.
struct PlanarView {
    vision::GrayView photo;
    geometry::Point2 offset_mm;  // where the machine put the camera, machine coordinates
};
PlanarMeasurement measure_planar_views(const models::MachineFile& machine,
                                       const geometry::CameraModel& camera,
                                       const geometry::BedPlane& plane,
                                       const std::vector<PlanarView>& views,
                                       const PlanarMeasureSettings& settings = {});

struct PlanarSolveOptions {
    // Beyond this the measurement is of something else (a wrong pitch, another sheet): a
    // machine this far off is broken, not out of calibration, and nothing is written for it.
    double max_error_mm = 10;
};

// Where a planar result was measured: the machine coordinates of the work zero in force while
// the target ran (commanded positions are in that work frame), where that figure came from, the
// machine's travel in machine coordinates, and its firmware (what a job's words mean).
struct PlanarFrame {
    geometry::Point2 work_zero_mm;
    std::string work_zero_from;  // "the machine file", "the controller's G54 ($#)"
    double travel_min_x_mm = 0, travel_min_y_mm = 0, travel_max_x_mm = 0, travel_max_y_mm = 0;
    std::string firmware;
    std::string kind;
};
// The frame a machine file states (work zero, travel, firmware).
PlanarFrame planar_frame_of(const models::MachineFile& machine);
// grbl's `$#` report ("[G54:-300.000,-300.000,0.000]" among its lines): the zero of `system`
// ("G54" .. "G59") in machine coordinates, when the replies carry it.
std::optional<geometry::Point2> grbl_work_zero_of(const std::vector<std::string>& replies,
                                                  const std::string& system);

struct PlanarSolution {
    std::string machine_fingerprint;
    double tool_length_mm = 0;
    models::PlanarFit fit;
    std::vector<geometry::Point2> commanded_mm;  // per measured hole
    std::vector<geometry::Point2> error_mm;      // seen - commanded, machine frame, placement out
    models::NormStatistics before;               // of error_mm
    models::NormStatistics after;     // of the fit's residuals: what the correction leaves there
    double measurement_sigma_mm = 0;  // RMS of the holes' uncertainties
    // The rigid part of the fitted field over the valid area, left out of the correction: the
    // work's zero and heading are set by hand on the machine.
    models::SmallRigidMotion rigid_part;
    // The drives' slack along x and y: where the hole drilled from the other side lies against
    // the model (not part of the model: the target takes it up the same way at every hole).
    std::optional<geometry::Point2> backlash_mm;
    // The work area the correction is valid over (the measured holes' extent), in the frame
    // the target ran in.
    double min_x_mm = 0, min_y_mm = 0, max_x_mm = 0, max_y_mm = 0;
    // The frame it was measured in. Results written before calbox recorded it have none, and
    // compensate nothing.
    std::optional<PlanarFrame> frame;
    // Whether the photos' bed frame is mirrored against the machine's (PlanarMeasurement's
    // `mirrored`): with the placement above, where the camera's bed lies in the machine's frame.
    // Results written before calbox recorded it have none, and give no bed view.
    std::optional<bool> bed_mirrored;
};

// Throws PlanarError (or models::PlanarModelError) with one line; nothing is returned for a
// machine then.
PlanarSolution solve_planar(const models::MachineFile& machine, const PlanarMeasurement& measured,
                            const PlanarSolveOptions& options = {});

// Where to command so that the tool lands on `intended` (X_c = X_t - e(X_c)).
geometry::Point2 planar_command_for(const PlanarSolution& solution, geometry::Point2 intended_mm);

// The firmware's own knobs for the part of the error they can carry: lines to send or to put in
// a configuration, each with what it leaves uncorrected.
struct FirmwareSettings {
    std::vector<std::string> lines;  // G-code commands, configuration lines and comments
    // The linear part they carry: each axis's travel too far (relative) and x's movement per mm
    // of y (the firmware's correction is x' = x - skew y, then each axis scaled by 1 / (1 + s)).
    double scale_x = 0, scale_y = 0, skew = 0;
    // The mean error norm left over the measured holes when only these settings are applied.
    double mean_left_mm = 0;
    double mean_before_mm = 0;
};
FirmwareSettings planar_firmware_settings(const models::MachineFile& machine,
                                          const PlanarSolution& solution);

// The mode's files: `calbox.planar-measurements/1`, `calbox.planar-result/1`. Reading throws
// RecordError naming `source`.
std::string planar_measurements_to_json(const PlanarMeasurement& measured);
PlanarMeasurement planar_measurements_from_json(const std::string& text, const std::string& source);
std::string planar_result_to_json(const PlanarSolution& solution, const FirmwareSettings& firmware);
PlanarSolution planar_result_from_json(const std::string& text, const std::string& source);

}  // namespace calbox::modes
