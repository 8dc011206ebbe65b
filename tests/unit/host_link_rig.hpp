#pragma once
// What the host link tests (test_host_link*.cpp) share: the twins' hosts and a delta's geometry
// worked by hand.
#include <CppUTest/TestHarness.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <thread>

#include "board/sim/duet_twin.hpp"
#include "board/sim/moonraker_twin.hpp"
#include "board/sim/octoprint_twin.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/sim_board.hpp"
#include "core/models/delta_commands.hpp"
#include "core/models/klipper_config.hpp"
#include "core/models/machine_file.hpp"
#include "core/models/machine_import.hpp"
#include "drivers/http_client.hpp"
#include "drivers/http_server.hpp"
#include "drivers/network.hpp"
#include "drivers/tls.hpp"
#include "firmware/cycle/cycle_mode.hpp"
#include "firmware/links/duet_link.hpp"
#include "firmware/links/moonraker_link.hpp"
#include "firmware/links/octoprint_link.hpp"
#include "firmware/loop/event_loop.hpp"
#include "tests/unit/link_request.hpp"

using namespace calbox;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

namespace host_link_rig {

inline models::DeltaGeometry example_geometry() {
    models::DeltaGeometry g;
    g.diagonal_rod_mm = 251.0;
    g.diagonal_rod_trim_mm = {0.5, -0.25, -0.25};
    g.radius_mm = 139.2;
    g.tower_angle_trim_deg = {0.25, -0.4, 0.15};
    g.endstop_offset_mm = {0, -0.18, -0.3};
    g.height_mm = 301.7;
    return g;
}

// The SAVE_CONFIG block's lines: everything from its first "#*#".
inline std::string block_of(const std::string& cfg) {
    return cfg.substr(cfg.find("#*#"));
}

}  // namespace host_link_rig

using namespace host_link_rig;
