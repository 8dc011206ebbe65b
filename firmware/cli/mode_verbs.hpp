#pragma once
// A mode's verbs on the command line, `calbox target|measure|solve MODE`: each mode's three in
// its own file (cli/<mode>_verbs.cpp), listed once in mode_verbs(); and what they share: the
// set-up every measure reads, the job's preview, the options they have in common.
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_file.hpp"
#include "firmware/cli/cli_args.hpp"

namespace calbox::cli {

struct ModeVerbs {
    std::string name;      // "delta", as the verbs take it
    std::string machines;  // what it calibrates, for `calbox --help` (machine_kinds.hpp)
    Command target, measure, solve;
};
ModeVerbs delta_verbs();
ModeVerbs galvo_verbs();
ModeVerbs planar_verbs();
// Every mode's, in the order `calbox --help` lists them.
std::vector<ModeVerbs> mode_verbs();
// "modes: delta (delta 3D printers), ...", wrapped at `width` columns, for `calbox --help`.
std::string modes_line(std::size_t width);

// What every measure command reads first: the camera, the bed plane and the machine.
struct SetUp {
    geometry::CameraModel camera;
    geometry::BedPlane plane;
    models::MachineFile machine;
};
SetUp read_set_up(const Args& args);

// A job drawn (--preview): perimeters, infill, traces and travel, with its length and time.
void draw_preview(const std::string& path, const jobs::PlacedJob& job,
                  const models::MachineFile& machine);

// The options the verbs share.
Option describe_option();          // target: --describe
Option camera_option();            // measure: --camera
Option plane_option();             // measure: --plane
Option measurements_out_option();  // measure: -o measurements.json
Option measurements_option();      // solve: --measurements
Option result_out_option();        // solve: -o result.json

}  // namespace calbox::cli
