#pragma once
// The delta mode's measure step: photos of the printed delta target -> each marker corner's
// position on the bed, paired with where the target commanded it.
#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/solve/delta_fit.hpp"
#include "core/targets/delta_target.hpp"
#include "core/vision/markers.hpp"

namespace calbox::modes {

class MeasureError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// One of the classic bars, measured between its end ticks' centrelines along the bar (where
// the nozzle went, whatever the strands' widths).
struct BarLengthMeasurement {
    char tower = 'A';
    double commanded_from_mm = 0, commanded_to_mm = 0;  // the ticks' distances from the centre
    double commanded_mm = 0;                            // far tick minus near tick
    double measured_mm = 0;
    double sigma_mm = 0;
    double surface_height_mm = 0;  // mean of the ticks' printed heights they were mapped at
    // Where the bar's centreline crosses the inner and outer ticks' in the first photo, on the
    // bed frame at the height they were mapped at: where to draw the bar on that photo.
    std::array<geometry::Point3, 2> ticks_seen_mm{};
};

struct DeltaMeasurement {
    targets::DeltaTarget target;
    std::vector<solve::FeatureMeasurement> features;  // one per marker corner seen
    std::vector<BarLengthMeasurement> bars;           // those fully seen in every photo
    // The others, each with why: "bar A: photo 1: its outer end tick ...".
    std::vector<std::string> bars_unmeasured;
    // Markers a photo should show (inside its frame) but could not read, each with where:
    // "photo 1: marker 7 near (1234, 567) px could not be read".
    std::vector<std::string> markers_unread;
    // Markers read whose ring strand could not be measured (their corners are not features):
    // "photo 1: marker 7's ring: its top side showed the strand in 3 of 60 profiles ...".
    std::vector<std::string> rings_unmeasured;
    // Corners placed but whose strand's width (their height) could not be told, each with why:
    // "photo 1: marker 7's corner 2: its top side: the lens's blur across the strand (1.14 px)
    // is over 0.33 of its width (3.31 px)". Their heights come from the surface fit.
    std::vector<std::string> heights_unmeasured;
    std::vector<std::vector<vision::DetectedMarker>> frames;  // what each photo showed
    double bed_scale = 1;  // the print in the photos against as printed (the bed's expansion)
    // The features stand at the heights their strands' widths give; the bars' ends are mapped
    // at the surface heights a fit of the features gives, else at the nominal height.
    bool heights_from_fit = false;
    // Otherwise why not, and what was done instead (the bar ends stay at the target's height).
    std::string heights_fallback;
};

// A corner's feature id: "m" marker id "c" corner index (OpenCV's order).
std::string corner_feature_id(int marker_id, int corner);

// Throws MeasureError with one line for a photo that cannot be measured: over- or
// under-exposed (its bright part clipped), no markers, markers that are not this target's or
// not laid out as it lays them (a photo of another target), or under three quarters of the
// target's markers in view. Positions are given as printed: when the photos were taken with the bed
// at `photo_bed_temperature_c` rather than the machine's bed_temperature_c, the bed's expansion
// (bed_material) is taken out.
DeltaMeasurement measure_delta(const models::MachineFile& machine,
                               const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               const std::vector<vision::GrayView>& frames,
                               std::optional<double> photo_bed_temperature_c = {});

// What a measurement leaves for the solve (the measurements file, `calbox.measurements/1`).
struct DeltaMeasurementsRecord {
    std::string machine_fingerprint;
    std::string target_fingerprint;
    std::vector<std::string> photos;
    double bed_scale = 1;
    bool heights_from_fit = false;
    std::string heights_fallback;
    std::vector<std::string> bars_unmeasured;
    std::vector<std::string> heights_unmeasured;
    std::vector<solve::FeatureMeasurement> features;
    std::vector<BarLengthMeasurement> bars;
};
DeltaMeasurementsRecord record_of(const DeltaMeasurement& measured,
                                  const models::MachineFile& machine,
                                  std::vector<std::string> photos);

// The measured corners against the commanded ones after the best rotation and translation of
// the target on the bed: what an overlay draws, magnified.
struct PlacementErrors {
    geometry::RigidPlacement placement;      // commanded -> bed
    std::vector<geometry::Point2> error_mm;  // per feature: measured - placed commanded
    double rms_mm = 0, largest_mm = 0;
};
PlacementErrors placement_errors(const std::vector<solve::FeatureMeasurement>& features);

class SolveError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

enum class DeltaMethod { fit, classic };
struct DeltaSolveOptions {
    std::string firmware;  // marlin | rrf | klipper; empty: the machine file's
    DeltaMethod method = DeltaMethod::fit;
};

// A solve's outcome (the result file, `calbox.delta-result/1`): the fit always runs (it reports
// what the data determine); `after` is what is sent, from the fit or the classic bars.
struct DeltaSolution {
    DeltaMethod method = DeltaMethod::fit;
    std::string firmware;
    std::string machine_fingerprint;
    solve::DeltaFitResult fit;
    models::DeltaGeometry after;
    std::vector<std::string> commands;  // the exact lines to send (Klipper: a printer.cfg section)
    std::size_t classic_bars = 0;       // bars the classic method averaged
    // The gap's heights came from a probe (a file, or the printer's own over the link), not from
    // the first layer's strands: known everywhere, one pass suffices.
    bool heights_from_probe = false;
};

// The delta mode's solve, policy included: the measurements must be this machine's, the
// firmware one calbox writes for, the correction within the machine file's [limits]. Throws
// SolveError or solve::FitError with one line; nothing is returned to send.
DeltaSolution solve_delta(const models::MachineFile& machine,
                          const DeltaMeasurementsRecord& measurements,
                          const std::vector<solve::ProbePoint>& probe,
                          const DeltaSolveOptions& options = {});

// Calibrating until the printer holds. A first layer laid where the nozzle's gap varies by
// tenths of a millimetre is pressed in one place, a free bead or a scraped trace in another: it
// measures the printer less well than one laid on a level bed. A first pass whose fit found the
// gap varying by more than `gap_range_limit_mm` is followed by another: its verification print,
// laid on the bed that pass levelled, is measured and fitted as the next pass, and so on until a
// pass's correction would move the nozzle by no more than `holds_within_mm` anywhere on the
// printable area (XY, a turn or shift of the whole print taken out, and height): it sends
// nothing, the printer holds. The last pass allowed sends its correction and says so. A pass
// whose heights a probe measured knows the gap however the strands lay: it is the only one.
struct DeltaPassLimits {
    double gap_range_limit_mm = 0.1;
    double holds_within_mm = 0.01;
    int max_passes = 3;
};

// What follows pass `pass` (from 1), given its solution.
enum class DeltaPassStep {
    apply,                        // send the correction; the cycle ends with its verification
    apply_then_measure_again,     // send it; its verification print is the next pass
    holds,                        // send nothing: a later pass found the printer within tolerance
    apply_and_stop_out_of_passes  // the last pass allowed still changed more: send it, stop
};
DeltaPassStep next_delta_pass_step(const DeltaSolution& solution, int pass,
                                   const DeltaPassLimits& limits = {});
// One line for the log and the record: what the pass found and what follows.
std::string describe_delta_pass(const DeltaSolution& solution, int pass, DeltaPassStep step,
                                const DeltaPassLimits& limits = {});
// A step in a few words, for the console and its JSON: "sent", "sent, measured again",
// "holds, nothing sent", "sent, no pass left".
const char* pass_step_name(DeltaPassStep step);

std::string method_name(DeltaMethod method);
DeltaMethod parse_method(const std::string& name);  // throws SolveError

}  // namespace calbox::modes
