#pragma once
// The galvo mode: a photo of the burned circle grid -> where each mark landed, indexed on the
// grid whatever way round the photo shows it; the field map and its correction table; the
// mode's files. The command line and `calbox run` call these.
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/models/galvo_field.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/record_error.hpp"
#include "core/targets/galvo_target.hpp"
#include "core/vision/spots.hpp"

namespace calbox::modes {

class GalvoError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct GalvoMeasureSettings {
    targets::GalvoTargetOptions target;
    vision::SpotSettings spots;
    // A mark is looked for this far (in pitches) from where its neighbours predict it: half a
    // pitch would take the next node's mark; a third leaves room for distortion that changes by
    // a few hundredths of a pitch from one node to the next.
    double match_reach_pitch = 0.33;
    // A blob whose second moments are more elongated than this is not a clean mark (spatter
    // fused to it, a double burn): it is reported, not measured.
    // A clean burned disc seen through the lens is round to a percent or two.
    double max_elongation = 1.06;
    // Marks of one kind are burned alike: one whose equivalent radius differs from its kind's
    // median by more than this fraction has something fused to it or missing from it.
    double max_radius_deviation = 0.04;
};

struct GalvoNodeMeasurement {
    targets::GridIndex index;
    geometry::Point2 intended_mm;  // scanner mm, the target's nominal grid
    bool large = false;
    geometry::Point2 measured_mm;  // bed frame, at the substrate's height
    double sigma_mm = 0;           // standard uncertainty of each coordinate
};

struct GalvoMeasurement {
    std::string machine_fingerprint, target_fingerprint;
    std::vector<std::string> photos;
    int grid_count = 0;
    double pitch_mm = 0;
    int symmetry = 0;  // how the photo's grid maps onto the target's (targets::apply_symmetry)
    bool dark_marks = true;
    std::vector<GalvoNodeMeasurement> nodes;
    std::vector<targets::GridIndex> missing;  // grid nodes with no measurable mark
    std::vector<geometry::Point2> extra_mm;   // blobs that are no mark of the grid (spatter)
};

// Throws GalvoError with one line when the photo cannot be indexed (no marks, not this grid,
// part of it outside the photo, an orientation the large marks do not settle).
GalvoMeasurement measure_galvo(const models::MachineFile& machine,
                               const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               const vision::GrayView& photo,
                               const GalvoMeasureSettings& settings = {});

struct GalvoSolveOptions {
    int table_nodes = 65;
    // The largest correction a scanner plausibly needs, as a fraction of its field: beyond it
    // the measurement is of something else (a wrong field size, another target) and nothing is
    // written for a controller.
    double max_correction_fraction = 0.03;
};

struct GalvoSolution {
    std::string machine_fingerprint;
    models::FieldFit fit;
    std::vector<geometry::Point2> intended_mm;  // per grid node, row by row
    double measurement_sigma_mm = 0;            // RMS of the nodes' uncertainties
    double predicted_rms_mm = 0;  // what the next burn should show: nodes' scatter, table's cells
    int pass = 1;                 // 1 from the uncorrected scanner, n after n - 1 tables
    // The scanner's square field's side: a job's point beyond it is refused. Results written
    // before calbox recorded it have none.
    std::optional<double> field_size_mm;
};

// `burned_through` is the table the grid was burned through (none on the first pass): the new
// table then refines it. Throws GalvoError (or models::FieldError) with one line; nothing is
// returned for a controller then.
GalvoSolution solve_galvo(const models::MachineFile& machine, const GalvoMeasurement& measured,
                          const std::optional<GalvoSolution>& burned_through,
                          const GalvoSolveOptions& options = {});

// The mode's files (text in, text out): `calbox.galvo-measurements/1`, `calbox.galvo-result/1`.
// Reading throws RecordError naming `source`.
std::string galvo_measurements_to_json(const GalvoMeasurement& measured);
GalvoMeasurement galvo_measurements_from_json(const std::string& text, const std::string& source);
std::string galvo_result_to_json(const GalvoSolution& solution);
GalvoSolution galvo_result_from_json(const std::string& text, const std::string& source);

}  // namespace calbox::modes
