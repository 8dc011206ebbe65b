#pragma once
// The machine kinds, declared once: the machine file's reader takes its choices and its
// refusals from here, the machine file's predicates (is_delta(), is_printer(), ...) their
// answers, the box's cycle its mode (firmware/modes/make_mode.cpp, one case per family, which
// the compiler checks) and the sim board its twins (board/sim/twin_kind.cpp, one row per kind,
// checked at compile time against this list). A new kind: a row here, its twin's row, its docs
// and its tests (docs/architecture.md, "A new machine kind").
#include <array>
#include <set>
#include <string>
#include <string_view>

#include "core/models/kind_table.hpp"

namespace calbox::models {

// The mode that measures a kind and fits its model.
enum class MachineFamily {
    delta,   // delta kinematics from a printed ArUco pattern
    planar,  // a gantry's quasi-static error model from a grid of holes or dots
    galvo,   // a galvo's field map from a burned circle grid
};

// What makes the marks: the target's holes or dots and the jobs' working moves.
enum class MachineTool {
    extruder,  // a printer's plastic
    spindle,   // a router's cutter: holes drilled, jobs cut below the surface
    beam,      // a laser's spot
};

struct MachineKind {
    std::string_view name;  // the machine file's [machine] kind
    std::string_view what;  // in the owner's words, plural: "CNC routers"
    MachineFamily family;
    MachineTool tool;
    bool printer;            // prints in plastic: extrusion, temperatures, a bed's origin
    bool jobs_at_work_zero;  // its jobs are written around a work zero the operator sets
    // A planar kind's holes as the camera sees them by default ([planar] holes); "" otherwise.
    std::string_view planar_holes;
    std::string_view docs;  // the page that explains its calibration
};

inline constexpr std::array<MachineKind, 5> kMachineKinds{{
    {"delta", "delta 3D printers", MachineFamily::delta, MachineTool::extruder, true, false, "",
     "docs/delta.md"},
    {"cartesian", "cartesian 3D printers", MachineFamily::planar, MachineTool::extruder, true,
     false, "light", "docs/planar.md"},
    {"router", "CNC routers", MachineFamily::planar, MachineTool::spindle, false, true, "dark",
     "docs/planar.md"},
    {"laser", "gantry lasers", MachineFamily::planar, MachineTool::beam, false, true, "dark",
     "docs/planar.md"},
    {"galvo", "galvo laser scanners", MachineFamily::galvo, MachineTool::beam, false, false, "",
     "docs/galvo.md"},
}};

// The row of `name`; nullptr for none.
constexpr const MachineKind* machine_kind(std::string_view name) {
    for (const auto& k : kMachineKinds)
        if (k.name == name) return &k;
    return nullptr;
}

// Whether `rows` (a table elsewhere, each row's `kind` a kind's name) holds every kind, each
// once, and nothing else: the compile-time check of a twin's table.
template <class Rows>
constexpr bool names_every_machine_kind(const Rows& rows) {
    return names_each_kind_once(kMachineKinds, rows);
}

std::string machine_kind_list(std::string_view separator);  // "delta|cartesian|..."
std::set<std::string> machine_kind_names();                 // the machine file's choices
// What a family's mode calibrates, for `calbox --help`: "cartesian 3D printers, CNC routers and
// gantry lasers".
std::string family_machines(MachineFamily family);

}  // namespace calbox::models
