#pragma once
// The box `calbox run` and `calbox revert` stand up: the board --board chooses (its devices, the
// machine beside them, the sim board's twin), the data directory, and the appliance on the real
// clock built from them.
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "board/devices.hpp"
#include "board/rpi/rpi_board.hpp"
#include "board/sim/sim_board.hpp"
#include "firmware/app/appliance.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/links/make_link.hpp"

namespace calbox::cli {

// Where the machine and the records are, as run and revert both take them.
struct Common {
    std::string scenario;
    std::filesystem::path data_dir;
};
Common common_options(const Args& args, bool rpi_allowed = false);

// What `calbox run` was asked, checked together.
struct RunOptions {
    bool automatic = false;       // --auto
    bool operator_hands = false;  // --operator-hands
    bool operator_acts = false;   // the sim board's operator does what the prompts ask
    bool on_rpi = false;
    std::optional<int> frames;
};

// The board --board chose: its devices (one type, whichever board), the machine beside them,
// and on the sim board the twin (its bench for the operator and the judge, its own commands).
struct ChosenBoard {
    std::unique_ptr<sim::SimBoard> sim;
    board::Devices own;  // a real board's devices
    models::MachineFile machine;
    board::Devices& devices() { return sim ? sim->devices : own; }
};

// The Pi's devices as --board-file says (or /etc/calbox/board.toml, or the defaults).
board::RpiSettings rpi_board_settings(const Args& args);

// The appliance on the real clock, built from the chosen board's devices as calbox run and
// calbox revert both use it. With --camera-files the photos come from files, not the board's
// camera.
struct Box {
    std::unique_ptr<hal::Clock> clock;
    ChosenBoard board;
    std::unique_ptr<hal::Camera> photo_files;
    std::unique_ptr<hal::Storage> data;
    firmware::Appliance appliance;
    firmware::Cycle& cycle = appliance.cycle;
    firmware::EventLoop& loop = appliance.loop;

    // `link`: the configuration's link.* over the machine file's [link].
    Box(const Args& args, const Common& common, firmware::CycleSettings settings,
        const firmware::Cycle::Log& log = board::log_to_standard_error,
        const firmware::LinkSettings& link = {});

    // The boards the sim board's person holds are the ones the box asks for.
    firmware::CycleSettings with_board(firmware::CycleSettings settings) const;
    // The board's network: every board has one.
    hal::Network& network();
};

}  // namespace calbox::cli
