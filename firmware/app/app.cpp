// calbox run: the appliance. The composition root: reads the options and the configuration, stands
// the box up on a board's devices (box.hpp), starts its parts from their list (box_parts.hpp) and
// runs the loop. calbox revert: the last backup, sent.
#include <cstdio>
#include <filesystem>

#include "board/sim/twin_judge.hpp"
#include "firmware/app/auto_placement.hpp"
#include "firmware/app/box.hpp"
#include "firmware/app/box_config.hpp"
#include "firmware/app/box_parts.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/version.hpp"
#include "firmware/loop/event_loop.hpp"
#include "firmware/net/box_news.hpp"

namespace calbox::cli {
namespace {

// `calbox run --auto`'s status when a signal stopped it before its verdict (0 is a goal met, 1
// one missed or a failure, 2 a usage error).
constexpr int kStoppedBeforeVerdict = 3;

RunOptions run_options(const Args& args) {
    RunOptions o;
    o.automatic = args.flag("--auto");
    if (o.automatic && args.flag("--operator")) throw UsageError("--auto already has the operator");
    o.operator_hands = args.flag("--operator-hands");
    if (o.operator_hands && (o.automatic || args.flag("--operator")))
        throw UsageError("--operator-hands is instead of --auto or --operator");
    o.operator_acts = o.automatic || args.flag("--operator") || o.operator_hands;
    if (args.get("--frames")) o.frames = static_cast<int>(args.number("--frames", 1));
    if (o.frames && (*o.frames < 1 || *o.frames > 16)) throw UsageError("--frames must be 1 to 16");
    o.on_rpi = args.get("--board").value_or("sim") == "rpi";
    if (!o.on_rpi && (args.get("--board-file") || args.get("--machine")))
        throw UsageError(
            "--board-file and --machine are the rpi board's (the sim board's machine "
            "is its scenario's)");
    if (o.on_rpi && (o.operator_acts || args.get("--camera-files")))
        throw UsageError(
            "--auto, --operator, --operator-hands and --camera-files are the sim "
            "board's");
    return o;
}

// The configuration: --config FILE, else DATA/calbox.toml when it exists (`config save` on the
// console writes it back there), with the options over it, each parsed once into its typed value
// and checked as the console checks it.
firmware::BoxConfig run_config(const Args& args, const std::filesystem::path& path) {
    firmware::BoxConfig config;
    if (args.get("--config") || std::filesystem::exists(path)) {
        try {
            config = firmware::BoxConfig::from_toml(read_input_file(path.string(), "configuration"),
                                                    path.string());
        } catch (const firmware::ConfigError& e) {
            throw UsageError(e.what());
        }
    }
    try {
        if (auto v = args.get("--web")) config.set("web.listen", *v);
        if (auto v = args.get("--web-tls")) config.set("web.tls_listen", *v);
        if (auto v = args.get("--mqtt")) config.set("mqtt.broker", *v);
    } catch (const firmware::ConfigError& e) {
        throw UsageError(std::string("--web/--web-tls/--mqtt: ") + e.what());
    }
    return config;
}

firmware::ModbusSettings modbus_settings(const Args& args, firmware::ModbusSettings modbus) {
    try {
        if (auto v = args.get("--modbus-server")) modbus.server = net::parse_modbus_endpoint(*v);
        if (auto v = args.get("--modbus-client")) modbus.client = net::parse_modbus_endpoint(*v);
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
    if (auto v = args.get("--modbus-map")) modbus.client_map = *v;
    if (auto v = args.get("--modbus-word-order")) {
        try {
            modbus.word_order = models::parse_word_order(*v);
        } catch (const std::invalid_argument& e) {
            throw UsageError(std::string("--modbus-word-order: ") + e.what());
        }
    }
    if (!modbus.client_map.empty() && !modbus.client)
        throw UsageError("--modbus-map needs --modbus-client");
    return modbus;
}

// The map of the results written to a controller: the whole block from register 0, or the
// --modbus-map file's. Read before the board starts, so that a bad file stops nothing half-open.
std::optional<firmware::ResultRegisterMap> result_map_of(const firmware::ModbusSettings& modbus) {
    if (!modbus.client) return std::nullopt;
    if (modbus.client_map.empty()) return firmware::ResultRegisterMap::whole_block(0);
    return firmware::ResultRegisterMap::from_toml(read_input_file(modbus.client_map, "Modbus map"),
                                                  modbus.client_map);
}

// After `calbox run --auto`: the box's own time, then the machine as the cycle left it, judged
// on a fresh job (through the correction the box keeps, when it keeps one) against the mode's
// goal.
int judged_run_end(Box& box, sim::TwinJudge& judge, const sim::TwinVerdict& before) {
    const auto& cycle = box.cycle;
    const auto& report = cycle.report();
    std::printf("box: %.2f s of its own work (measure, solve%s), camera %.2f s, machine %.2f s\n",
                report.box_seconds, report.number == 1 ? ", set-up" : "", report.camera_seconds,
                report.machine_seconds);
    if (cycle.cycles_completed() == 0)
        throw std::runtime_error("the cycle did not complete: " + (cycle.error().empty()
                                                                       ? std::string("cancelled")
                                                                       : cycle.error()));
    const auto after = judge.after(cycle.mode().kept_correction());
    std::printf("after: %s\n", after.line.c_str());
    const auto goal = cycle.mode().goal();
    if (const auto shortfall = goal.shortfall(before.figures, after.figures); !shortfall.empty())
        throw std::runtime_error("the " + goal.mode + " goal is not met: " + shortfall + " (goal " +
                                 goal.describe() + ")");
    if (box.board.sim->bench->scenario().placement) {
        const auto kept = cycle.mode().kept_result_text();
        if (!kept) throw std::runtime_error("placement: the box keeps no correction");
        firmware::judge_placement(*box.board.sim->bench, *box.data, *kept);
    }
    return 0;
}

// `calbox run`'s status once its loop is over. systemctl stop (SIGTERM) and Ctrl-C (SIGINT) are
// how a box is meant to be stopped: a clean stop, status 0, whatever the cycle was doing
// (cancelled: nothing half-sent stays in flight); with --auto, the twin's verdict.
int run_end(Box& box, const RunOptions& options, int stopped_by, sim::TwinJudge* judge,
            const std::optional<sim::TwinVerdict>& before) {
    if (stopped_by != 0) {
        board::log_to_standard_error(hal::LogLevel::info, "stopped by signal " +
                                                              std::to_string(stopped_by) + "; " +
                                                              box.appliance.link->closing_note());
        // --auto promises 0 only for a goal met: stopped before its verdict, it says so.
        if (options.automatic) {
            board::log_to_standard_error(hal::LogLevel::warning,
                                         "--auto: stopped before the verdict (exit status " +
                                             std::to_string(kStoppedBeforeVerdict) + ")");
            return kStoppedBeforeVerdict;
        }
        return 0;
    }
    if (!options.automatic) return 0;
    return judged_run_end(box, *judge, *before);
}

// --auto: one cycle, then out (once the controller has the whole result), judged by the twin's
// judge, not the box: the twin's truth before the cycle, for the before/after lines.
struct AutomaticRun {
    std::unique_ptr<sim::TwinJudge> judge;
    std::optional<sim::TwinVerdict> before;
    firmware::CycleSubscription one_cycle;
};

AutomaticRun start_automatic_run(Box& box, RunningBox& running) {
    AutomaticRun automatic;
    automatic.one_cycle = box.cycle.subscribe({{},
                                               {},
                                               [&running](bool) {
                                                   running.stop_when_settled = true;
                                                   running.part_settled();
                                               },
                                               {},
                                               {}});
    automatic.judge = sim::make_twin_judge(*box.board.sim->bench);
    automatic.before = automatic.judge->before();
    std::printf("before: %s\n", automatic.before->line.c_str());
    std::fflush(stdout);
    box.board.sim->lines->press(std::chrono::milliseconds(100));
    return automatic;
}

int run(const Args& args) {
    const RunOptions options = run_options(args);
    const Common common = common_options(args, true);
    const std::filesystem::path config_path = args.get("--config")
                                                  ? std::filesystem::path(*args.get("--config"))
                                                  : common.data_dir / "calbox.toml";
    firmware::BoxConfig config = run_config(args, config_path);
    const firmware::ModbusSettings modbus = modbus_settings(args, config.settings().modbus);
    auto result_map = result_map_of(modbus);

    firmware::SignalWatch signals;  // before any thread, so that every thread blocks them
    // The cycle's settings as the configuration says, the options over them.
    const auto settings_from = [&options](const firmware::BoxConfig& c) {
        auto s = c.settings().cycle;
        if (options.frames) s.frames_per_capture = *options.frames;
        return s;
    };
    firmware::LogBook log_book;
    std::function<void()> on_log;  // the network's windows, once they are there
    const firmware::Cycle::Log log = [&log_book, &on_log](hal::LogLevel level,
                                                          const std::string& line) {
        board::log_to_standard_error(level, line);
        log_book.add(line);
        if (on_log) on_log();
    };
    Box box(args, common, settings_from(config), log, config.settings().link);
    int stopped_by = 0;
    box.loop.watch(signals.fd(), [&] {
        stopped_by = signals.take();
        box.cycle.cancel("stopped by signal " + std::to_string(stopped_by));
        box.loop.stop();
    });

    firmware::BoxNews news(*box.data, calbox::build_version(), log);
    news.set_needs_calibration_mm(config.settings().report.needs_calibration_mm);
    RunningBox running{
        .args = args,
        .options = options,
        .box = box,
        .config = config,
        .config_path = config_path,
        .data_dir = common.data_dir,
        .modbus = modbus,
        .result_map = std::move(result_map),
        .log_book = log_book,
        .news = news,
        .log = log,
        .config_changed =
            [&] {
                box.cycle.set_settings(box.with_board(settings_from(config)));
                news.set_needs_calibration_mm(config.settings().report.needs_calibration_mm);
            },
        .on_log = on_log};
    StartedParts parts;
    parts.start_all(running);

    AutomaticRun automatic;
    if (options.automatic) {
        automatic = start_automatic_run(box, running);
    } else if (!running.console_wanted) {
        log("waiting for the button (no console)");
    }
    box.loop.run();
    return run_end(box, options, stopped_by, automatic.judge.get(), automatic.before);
}

int revert(const Args& args) {
    const Common common = common_options(args, true);
    firmware::SignalWatch signals;
    Box box(args, common, {});
    bool finished = false;
    const auto until_settled = box.cycle.subscribe({{},
                                                    [&box, &finished](firmware::CycleState state) {
                                                        if (state == firmware::CycleState::idle ||
                                                            state == firmware::CycleState::error) {
                                                            finished = true;
                                                            box.loop.stop();
                                                        }
                                                    },
                                                    {},
                                                    {},
                                                    {}});
    const std::string refused = box.cycle.revert();
    if (!refused.empty()) throw std::runtime_error(refused);
    if (finished) {
        // A galvo's or router's correction is the box's own file, put back at once: nothing to
        // wait for.
        std::printf("reverted: the correction in force before cycle %d is back\n",
                    box.cycle.report().number);
        return 0;
    }
    int stopped_by = 0;
    box.loop.watch(signals.fd(), [&] {
        stopped_by = signals.take();
        box.cycle.cancel("stopped by signal " + std::to_string(stopped_by));
        box.loop.stop();
    });
    box.loop.run();
    if (stopped_by != 0)
        throw std::runtime_error("revert: stopped by signal " + std::to_string(stopped_by) +
                                 " before the printer confirmed the settings");
    if (box.cycle.state() == firmware::CycleState::error)
        throw std::runtime_error(box.cycle.error());
    std::printf("reverted: the printer reports the settings saved before cycle %d\n",
                box.cycle.report().number);
    return 0;
}

// Where the machine and the records are, as run and revert both take them.
std::vector<Option> where_options() {
    return {
        {"--board", "sim|rpi",
         "rpi: a Raspberry Pi 4 or 5 with its camera (V4L2), button, LEDs and light\n"
         "(GPIO), display (I2C) and the machine's serial port, where --board-file says;\n"
         "a device that is not there stops it with one line naming it.\n"
         "sim: the digital twin (the default)"},
        {"--scenario", "FILE",
         "the sim board's machine, its hidden errors, the camera and the set-up boards\n"
         "(default examples/delta_cycle.toml; examples/galvo_cycle.toml is a galvo\n"
         "scanner, examples/planar_cycle.toml a router)"},
        {"--data", "DIR",
         "set-up and cycle records (default $XDG_STATE_HOME/calbox, else\n"
         "~/.local/state/calbox)"},
        {"--board-file", "FILE",
         "the Pi's devices (default /etc/calbox/board.toml when it exists;\n"
         "docs/devices.md, The Raspberry Pi board)"},
        {"--machine", "FILE", "with --board rpi: the machine beside the box"},
    };
}

}  // namespace

std::vector<Command> appliance_commands() {
    std::vector<Option> run_options = where_options();
    const std::vector<Option> more = {
        {"--config", "FILE",
         "the box's configuration (TOML; docs/appliance.md, Configuration; default\n"
         "DIR/calbox.toml when it exists); the options override it"},
        {"--console", "DEVICE",
         "the console: a serial device, \"pty\" (a pseudo-terminal, linked as\n"
         "DIR/console), \"stdin\" (the default: standard input when it is a terminal)\n"
         "or \"\" for none; overrides console.device"},
        {"--auto", "",
         "no person: the sim board's operator does what each prompt asks and presses\n"
         "the button; one cycle, then exit with the twin's verdict (below)",
         Given::flag},
        {"--operator", "",
         "the sim board's operator does what the set-up and bed prompts ask; the start\n"
         "and the review are left to the button, the console or a PLC",
         Given::flag},
        {"--operator-hands", "",
         "the operator does what each prompt asks but presses nothing: every press\n"
         "comes from the console or the button",
         Given::flag},
        {"--frames", "N", "photos averaged per capture (default: cycle.frames_per_capture, 1)"},
        {"--camera-files", "DIR|GLOB",
         "photos from image files (name order, one per frame) instead of the camera;\n"
         "their size must be the calibration's (camera.yaml)"},
        {"--modbus-server", "ENDPOINT",
         "serve the PLC map (docs/devices.md, Modbus); ENDPOINT is tcp:HOST:PORT\n"
         "(0.0.0.0 for all interfaces) or rtu:DEVICE:BAUD"},
        {"--modbus-client", "ENDPOINT",
         "after each completed cycle, write its result into that controller's holding\n"
         "registers: the whole result block from register 0, or as --modbus-map says"},
        {"--modbus-map", "FILE", "with --modbus-client: TOML lines value_name = register"},
        {"--modbus-word-order", "ORDER",
         "the floats' word order on Modbus: abcd (default: 123456.0 is 0x47F1 0x2000),\n"
         "cdab, badc or dcba"},
        {"--web", "HOST:PORT",
         "serve the box's web page there (docs/network.md; overrides web.listen);\n"
         "port 0 takes a free one (logged). Whatever changes state needs the password\n"
         "set with the console's `web password`"},
        {"--web-tls", "HOST:PORT",
         "serve the page over https there (overrides web.tls_listen), with web.tls_cert\n"
         "and web.tls_key or the box's own self-signed certificate; --web's port then\n"
         "only redirects to it. `web tls` on the console shows the fingerprint"},
        {"--mqtt", "HOST:PORT",
         "report to that MQTT broker (overrides mqtt.broker): the state, each cycle's\n"
         "result, availability and Home Assistant's discovery"},
    };
    run_options.insert(run_options.end(), more.begin(), more.end());
    return {
        {"run", "the appliance: the one-button calibration cycle", run_options,
         R"(The appliance: waits for the button, then runs the calibration cycle of the scenario's
machine (a delta printer, a galvo scanner or a router): the target made over the machine
link, lit and photographed, measured, solved, shown for review (short press applies, long
press cancels), applied, and verified by making the target again. A delta printer's
settings are sent with a backup and a read-back; a galvo scanner's correction is a table
the box keeps (DIR/galvo-table.json) and sends jobs through, the grid burned through it to
verify; a router's or cartesian printer's is an error model the box keeps
(DIR/planar-result.json, with the firmware's own scale and skew settings beside it in the
cycle's firmware.txt) and compensates jobs through, the holes drilled through it to verify.
The correction starts from the settings the printer reports (M503; RepRapFirmware: M665,
M666), not the scenario's. The first time (no camera.yaml / plane.yaml in DIR) it first
asks for views of a chessboard held in front of the camera and for one on the bed (the
scenario's [setup]: chessboard:11x8@20 and 9x6@20 unless it says otherwise). Every state
change is one line on standard error.

With --auto it prints the twin's judgement before and after, and exits 0 only if the goal
is met: a delta's XY RMS <= 0.01 mm, worst <= 0.03 mm over the printable area; a galvo's
marks through the table <= 0.008 mm mean, <= 0.03 mm worst; a router's (or printer's)
fresh points through the model under 0.05 mm mean and 95 % less than before; 1 when it is
not met or the cycle failed; 3 when SIGTERM or SIGINT stopped it before the verdict.
Without --auto a signal is a clean stop, status 0.

The console's commands: help, status, config list|get|set|save|reset, start, confirm,
cancel, revert, last, log, version, camera calibrate|plane, capture; on the sim board also
press, hold and quit.)",
         run},
        {"revert", "put back what the last applied cycle changed", where_options(),
         R"(Sends the settings backed up before the last completed cycle applied its correction
(DIR/cycle-NNNN-backup.gcode), then M500, and reads them back from the printer (M503;
RepRapFirmware: M665, M666); exits 1 if the printer reports anything else. The sim
board's printer keeps what it stores in DIR/twin-printer-settings.gcode, as an EEPROM.)",
         revert},
    };
}

}  // namespace calbox::cli
