#include "firmware/app/box.hpp"

#include <cstdio>
#include <cstdlib>

#include "firmware/app/sim_appliance.hpp"

#ifndef CALBOX_EXAMPLES_DIR
#define CALBOX_EXAMPLES_DIR "examples"
#endif

namespace calbox::cli {
namespace {

std::filesystem::path default_data_dir() {
    if (const char* state = std::getenv("XDG_STATE_HOME"); state != nullptr && *state != 0)
        return std::filesystem::path(state) / "calbox";
    if (const char* home = std::getenv("HOME"); home != nullptr && *home != 0)
        return std::filesystem::path(home) / ".local" / "state" / "calbox";
    throw std::runtime_error(
        "no --data directory given and neither XDG_STATE_HOME nor HOME is set");
}

// A real board's devices are opened in order: the first one that is not there stops the box
// with one line naming it.
ChosenBoard choose_board(const Args& args, const Common& common, hal::Clock& clock,
                         const firmware::Cycle::Log& log) {
    ChosenBoard chosen;
    if (args.get("--board").value_or("sim") == "rpi") {
        const auto path = args.get("--machine");
        if (!path) throw UsageError("--board rpi needs --machine FILE: the machine beside the box");
        chosen.machine = models::parse_machine_file(read_input_file(*path, "machine file"), *path);
        chosen.own = board::open_rpi_devices(rpi_board_settings(args), clock);
        return chosen;
    }
    chosen.sim = std::make_unique<sim::SimBoard>(
        sim::make_sim_board({common.scenario, common.data_dir, 115200}, clock, log));
    chosen.machine = chosen.sim->machine;
    return chosen;
}

// The configuration's link.* over the machine file's [link].
ChosenBoard with_link(ChosenBoard chosen, const firmware::LinkSettings& link) {
    try {
        chosen.machine.link = link.over(chosen.machine);
    } catch (const firmware::ConfigError& e) {
        throw UsageError(std::string("configuration: ") + e.what());
    }
    if (chosen.sim) chosen.sim->machine.link = chosen.machine.link;
    return chosen;
}

}  // namespace

Common common_options(const Args& args, bool rpi_allowed) {
    const std::string board = args.get("--board").value_or("sim");
    if (board != "sim" && !(rpi_allowed && board == "rpi"))
        throw UsageError("unknown board '" + board + "': " + (rpi_allowed ? "sim or rpi" : "sim"));
    if (board == "rpi" && args.get("--scenario")) throw UsageError("--scenario is the sim board's");
    Common c;
    c.scenario = args.get("--scenario").value_or(CALBOX_EXAMPLES_DIR "/delta_cycle.toml");
    c.data_dir =
        args.get("--data") ? std::filesystem::path(*args.get("--data")) : default_data_dir();
    std::error_code ec;
    std::filesystem::create_directories(c.data_dir, ec);
    if (ec) throw std::runtime_error(c.data_dir.string() + ": cannot create: " + ec.message());
    return c;
}

board::RpiSettings rpi_board_settings(const Args& args) {
    const auto given = args.get("--board-file");
    const std::string path = given.value_or("/etc/calbox/board.toml");
    std::error_code ec;
    if (!given && !std::filesystem::exists(path, ec)) return board::default_rpi_settings();
    return board::read_rpi_settings(path);
}

Box::Box(const Args& args, const Common& common, firmware::CycleSettings settings,
         const firmware::Cycle::Log& log, const firmware::LinkSettings& link)
    : clock(board::monotonic_clock()),
      board(with_link(choose_board(args, common, *clock, log), link)),
      photo_files(args.get("--camera-files") ? board::photo_files(*args.get("--camera-files"))
                                             : nullptr),
      data(board::data_directory(common.data_dir)),
      appliance(firmware::ApplianceDevices::of(board.devices(), photo_files.get()), *data, *clock,
                {}, board.machine, with_board(std::move(settings)), log) {}

firmware::CycleSettings Box::with_board(firmware::CycleSettings settings) const {
    if (!board.sim) return settings;
    return firmware::SimAppliance::with_setup_boards(std::move(settings),
                                                     board.sim->bench->scenario().setup);
}

hal::Network& Box::network() {
    if (!board.devices().network) throw std::logic_error("the board opened no network");
    return *board.devices().network;
}

}  // namespace calbox::cli
