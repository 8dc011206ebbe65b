// calbox run: the appliance. The composition root: reads the options, asks a board for its
// devices, wires them to the event loop and the cycle. calbox revert: the last backup, sent.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "board/devices.hpp"
#include "board/rpi/rpi_board.hpp"
#include "board/sim/sim_board.hpp"
#include "board/sim/twin_judge.hpp"
#include "firmware/app/appliance.hpp"
#include "firmware/app/box_config.hpp"
#include "firmware/app/sim_appliance.hpp"
#include "firmware/app/sim_operator.hpp"
#include "firmware/cli/cli_args.hpp"
#include "firmware/cli/version.hpp"
#include "firmware/console/console.hpp"
#include "firmware/console/job_desk.hpp"
#include "firmware/console/link_key.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/links/gcode_host.hpp"
#include "firmware/loop/event_loop.hpp"
#include "firmware/net/box_network.hpp"
#include "firmware/net/box_news.hpp"
#include "firmware/net/web_password.hpp"
#include "firmware/plc/plc_link.hpp"

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

void log_line(const std::string& line) {
    std::fprintf(stderr, "calbox: %s\n", line.c_str());
}

struct Common {
    std::string scenario;
    std::filesystem::path data_dir;
};

Common common_options(const Args& args, bool rpi_allowed = false) {
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

// The board --board chose: its devices (one type, whichever board), the machine beside them,
// and on the sim board the twin (its bench for the operator and the judge, its own commands).
struct ChosenBoard {
    std::unique_ptr<sim::SimBoard> sim;
    board::Devices own;  // a real board's devices
    models::MachineFile machine;
    board::Devices& devices() { return sim ? sim->devices : own; }
};

board::RpiSettings rpi_board_settings(const Args& args) {
    const auto given = args.get("--board-file");
    const std::string path = given.value_or("/etc/calbox/board.toml");
    std::error_code ec;
    if (!given && !std::filesystem::exists(path, ec)) return board::default_rpi_settings();
    return board::read_rpi_settings(path);
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

// The appliance on the real clock, built from the chosen board's devices as calbox run and
// calbox revert both use it. With --camera-files the photos come from files, not the board's
// camera.
struct Box {
    std::unique_ptr<hal::Clock> clock = board::monotonic_clock();
    ChosenBoard board;
    std::unique_ptr<hal::Camera> photo_files;
    std::unique_ptr<hal::Storage> data = nullptr;
    firmware::Appliance appliance;
    firmware::Cycle& cycle = appliance.cycle;
    firmware::EventLoop& loop = appliance.loop;

    Box(const Args& args, const Common& common, firmware::CycleSettings settings,
        const firmware::Cycle::Log& log = log_line, const firmware::LinkSettings& link = {})
        : board(with_link(choose_board(args, common, *clock, log), link)),
          photo_files(args.get("--camera-files") ? board::photo_files(*args.get("--camera-files"))
                                                 : nullptr),
          data(board::data_directory(common.data_dir)),
          appliance(firmware::ApplianceDevices::of(board.devices(), photo_files.get()), *data,
                    *clock, {}, board.machine, with_board(std::move(settings)), log) {}

    // The configuration's link.* over the machine file's [link].
    static ChosenBoard with_link(ChosenBoard chosen, const firmware::LinkSettings& link) {
        try {
            chosen.machine.link = link.over(chosen.machine);
        } catch (const firmware::ConfigError& e) {
            throw UsageError(std::string("configuration: ") + e.what());
        }
        if (chosen.sim) chosen.sim->machine.link = chosen.machine.link;
        return chosen;
    }

    // The boards the sim board's person holds are the ones the box asks for.
    firmware::CycleSettings with_board(firmware::CycleSettings settings) const {
        if (!board.sim) return settings;
        return firmware::SimAppliance::with_setup_boards(std::move(settings),
                                                         board.sim->bench->scenario().setup);
    }
};

// The board's network: every board has one.
hal::Network& network_of(Box& box) {
    if (!box.board.devices().network) throw std::logic_error("the board opened no network");
    return *box.board.devices().network;
}

// `calbox run --auto`'s status when a signal stopped it before its verdict (0 is a goal met, 1
// one missed or a failure, 2 a usage error).
constexpr int kStoppedBeforeVerdict = 3;

// What `calbox run` was asked, checked together.
struct RunOptions {
    bool automatic = false;       // --auto
    bool operator_hands = false;  // --operator-hands
    bool operator_acts = false;   // the sim board's operator does what the prompts ask
    bool on_rpi = false;
    std::optional<int> frames;
};

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
        if (auto v = args.get("--mqtt")) config.set("mqtt.broker", *v);
    } catch (const firmware::ConfigError& e) {
        throw UsageError(std::string("--web/--mqtt: ") + e.what());
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

// The console's port: --console DEVICE, else the configuration's console.device (on the rpi
// board its file's console UART when neither says one). Null with `reopen` empty: no console.
struct ConsolePort {
    std::unique_ptr<hal::SerialPort> port;
    firmware::ConsoleLink::Reopen reopen;
    bool wanted() const { return port != nullptr || static_cast<bool>(reopen); }
};

ConsolePort open_console_port(const Args& args, const firmware::BoxConfig& config, bool on_rpi,
                              const std::filesystem::path& data_dir,
                              const firmware::Cycle::Log& log) {
    std::string device = args.get("--console").value_or(config.settings().console.device);
    if (on_rpi && !args.get("--console") && device == "stdin")
        device = rpi_board_settings(args).console_device;
    ConsolePort console;
    if (device == "pty") {
        auto pty = board::pseudo_terminal();
        const auto link = data_dir / "console";
        std::error_code ec;
        std::filesystem::remove(link, ec);
        std::filesystem::create_symlink(pty.path, link, ec);
        log("console on " + pty.path + (ec ? "" : " (" + link.string() + ")"));
        console.port = std::move(pty.port);
    } else if (device == "stdin") {
        // Standard input when it is a terminal; /dev/null (as under CI) leaves it off.
        if (::isatty(STDIN_FILENO) == 1) console.port = board::standard_io();
    } else if (!device.empty()) {
        // A UART, often a USB adapter: unplugged and plugged in again, or not there yet at the
        // start, it is opened again when it is back.
        console.reopen = [device, baud = config.settings().console.baud] {
            return board::serial_port(device, baud);
        };
        // A path that is there but cannot be opened (not a serial device, no permission) is a
        // set-up mistake that waiting does not mend: it stops the box with its reason.
        std::error_code ec;
        if (std::filesystem::exists(device, ec)) {
            console.port = console.reopen();
            log("console on " + device);
        } else {
            log("console: " + device + " is not there (opened when it is)");
        }
    }
    return console;
}

// The sim board's own console rows: press, hold, quit.
std::vector<firmware::ConsoleCommand> sim_board_commands(sim::SimBoard& board,
                                                         firmware::EventLoop& loop) {
    using Words = std::vector<std::string>;
    return {{"press", "press", "the sim board: a short press of the button",
             [&board](const Words&, std::string_view, firmware::ConsoleReply& r) {
                 board.lines->press(std::chrono::milliseconds(100));
                 r.text = "pressed";
             }},
            {"hold", "hold", "the sim board: a long press of the button",
             [&board](const Words&, std::string_view, firmware::ConsoleReply& r) {
                 board.lines->press(std::chrono::milliseconds(2000));
                 r.text = "held";
             }},
            {"quit", "quit", "the sim board: stop the box",
             [&loop](const Words&, std::string_view, firmware::ConsoleReply& r) {
                 loop.stop();
                 r.text = "stopping";
             }}};
}

std::string utc_now_text() {
    return firmware::utc_text(std::chrono::duration_cast<std::chrono::seconds>(
                                  std::chrono::system_clock::now().time_since_epoch())
                                  .count());
}

std::int64_t unix_now_s() {
    return static_cast<std::int64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                         std::chrono::system_clock::now().time_since_epoch())
                                         .count());
}

// The console and the parts with rows of their own on it (the web page's password, the job
// desk, OctoPrint's key, the sim board's button), read on its port; it tells the console what
// the cycle's prompts and notices say.
struct BoxConsole {
    bool wanted;
    std::unique_ptr<hal::Storage> config_home;
    std::optional<firmware::ConsoleLink> link;
    firmware::LinkKeyRequest link_key;
    firmware::JobDesk job_desk;  // jobs compensated through the correction the box keeps
    firmware::Console commands;
    firmware::CycleSubscription listening;

    BoxConsole(ConsolePort port, const std::filesystem::path& config_path,
               firmware::BoxConfig& config, Box& box, const firmware::LogBook& log_book,
               const firmware::Cycle::Log& log, std::function<void()> config_changed)
        : wanted(port.wanted()),
          config_home(board::data_directory(directory_of(config_path))),
          link_key(
              box.loop, box.board.machine.link, network_of(box).http(),
              [key_file = box.board.machine.link.key_file] {
                  return board::data_directory(directory_of(key_file));
              },
              logged_notice(log)),
          job_desk(box.loop, box.cycle, *box.appliance.link, *box.data, utc_now_text,
                   logged_notice(log)),
          commands(firmware::ConsoleContext{
              box.cycle, config, *config_home, config_path.filename().string(), *box.data, log_book,
              calbox::build_version(), config_changed, rows(config, box, config_changed)}) {
        if (wanted) {
            link.emplace(box.loop, std::move(port.port), commands, log, std::move(port.reopen),
                         box.clock.get());
        }
        listening = box.cycle.subscribe({[this](firmware::Prompt prompt, int) {
                                             if (prompt != firmware::Prompt::none)
                                                 notice(std::string("waiting: ") +
                                                        firmware::prompt_text(prompt));
                                         },
                                         {},
                                         {},
                                         [this](const std::string& line) { notice(line); },
                                         {}});
    }
    void notice(const std::string& line) {
        if (link) link->notice(line);
    }

  private:
    static std::filesystem::path directory_of(const std::filesystem::path& file) {
        return file.parent_path().empty() ? std::filesystem::path(".") : file.parent_path();
    }
    std::function<void(const std::string&)> logged_notice(const firmware::Cycle::Log& log) {
        return [this, log](const std::string& line) {
            log(line);
            notice(line);
        };
    }
    std::vector<firmware::ConsoleCommand> rows(firmware::BoxConfig& config, Box& box,
                                               const std::function<void()>& config_changed) {
        std::vector<firmware::ConsoleCommand> more = {
            firmware::web_password_row(config, network_of(box).passwords(), config_changed),
            job_desk.command(), link_key.command()};
        if (box.board.sim) {
            for (auto& row : sim_board_commands(*box.board.sim, box.loop))
                more.push_back(std::move(row));
        }
        return more;
    }
};

// The map of the results written to a controller: the whole block from register 0, or the
// --modbus-map file's. Read before the board starts, so that a bad file stops nothing half-open.
std::optional<firmware::ResultRegisterMap> result_map_of(const firmware::ModbusSettings& modbus) {
    if (!modbus.client) return std::nullopt;
    if (modbus.client_map.empty()) return firmware::ResultRegisterMap::whole_block(0);
    return firmware::ResultRegisterMap::from_toml(read_input_file(modbus.client_map, "Modbus map"),
                                                  modbus.client_map);
}

// The box's Modbus roles where the configuration or the options say: the PLC map it serves
// (listening to the cycle itself), and the controller it writes each completed cycle's result
// to. `written` is called when the last result queued has gone.
struct ModbusRoles {
    board::RegisterServer server;
    std::optional<firmware::PlcServer> plc;
    std::unique_ptr<hal::RegisterLink> client;
    std::optional<firmware::ResultWriter> writer;
    int results_written_for = 0;
    firmware::CycleSubscription listening;

    ModbusRoles(const firmware::ModbusSettings& modbus,
                const std::optional<firmware::ResultRegisterMap>& result_map,
                firmware::EventLoop& loop, firmware::Cycle& cycle, std::function<void()> written) {
        if (modbus.server) {
            namespace plc_map = firmware::plc;
            server = board::register_server(*modbus.server,
                                            {plc_map::kCoilCount, plc_map::kDiscreteInputCount, 0,
                                             firmware::input_register_count()},
                                            modbus.timeouts, log_line);
            plc.emplace(*server.server, cycle, modbus.word_order, log_line);
            loop.watch(server.server->written_fd(), [this] { plc->on_coils_written(); });
            log_line(modbus.server->describe() + ": serving the PLC map" +
                     (modbus.server->kind == net::ModbusEndpoint::Kind::tcp
                          ? " on port " + std::to_string(server.port)
                          : std::string()));
        }
        if (!modbus.client) return;
        client = board::register_client(*modbus.client, modbus.timeouts);
        writer.emplace(*client, *result_map, modbus.word_order, log_line);
        loop.watch(client->completion_fd(), [this, written = std::move(written)] {
            writer->on_completion();
            if (writer->idle()) written();
        });
        results_written_for = cycle.cycles_completed();
        listening = cycle.subscribe({{},
                                     {},
                                     [this, &cycle](bool) {
                                         if (cycle.cycles_completed() <= results_written_for)
                                             return;
                                         results_written_for = cycle.cycles_completed();
                                         writer->write(cycle.report(),
                                                       cycle.mode().result(cycle.report().applied));
                                     },
                                     {},
                                     {}});
    }
    bool idle() const { return !writer || writer->idle(); }
};

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
    return 0;
}

int run(const Args& args) {
    const RunOptions options = run_options(args);
    const Common common = common_options(args, true);
    const std::filesystem::path config_path = args.get("--config")
                                                  ? std::filesystem::path(*args.get("--config"))
                                                  : common.data_dir / "calbox.toml";
    firmware::BoxConfig config = run_config(args, config_path);
    const firmware::ModbusSettings modbus = modbus_settings(args, config.settings().modbus);
    const auto result_map = result_map_of(modbus);

    firmware::SignalWatch signals;  // before any thread, so that every thread blocks them
    // The cycle's settings as the configuration says, the options over them.
    const auto settings_from = [&options](const firmware::BoxConfig& c) {
        auto s = c.settings().cycle;
        if (options.frames) s.frames_per_capture = *options.frames;
        return s;
    };
    firmware::LogBook log_book;
    std::function<void()> on_log;  // the network's windows, once they are there
    const firmware::Cycle::Log log = [&log_book, &on_log](const std::string& line) {
        log_line(line);
        log_book.add(line);
        if (on_log) on_log();
    };
    Box box(args, common, settings_from(config), log, config.settings().link);
    firmware::EventLoop& loop = box.loop;
    firmware::Cycle& cycle = box.cycle;
    sim::SimBoard* sim_board = box.board.sim.get();

    int stopped_by = 0;
    loop.watch(signals.fd(), [&] {
        stopped_by = signals.take();
        cycle.cancel("stopped by signal " + std::to_string(stopped_by));
        loop.stop();
    });

    firmware::BoxNews news(*box.data, calbox::build_version(), log);
    news.set_needs_calibration_mm(config.settings().report.needs_calibration_mm);
    BoxConsole console(
        open_console_port(args, config, options.on_rpi, common.data_dir, log), config_path, config,
        box, log_book, log, [&] {
            cycle.set_settings(box.with_board(settings_from(config)));
            news.set_needs_calibration_mm(config.settings().report.needs_calibration_mm);
        });

    bool stop_when_written = false;
    ModbusRoles modbus_roles(modbus, result_map, loop, cycle, [&] {
        if (stop_when_written) loop.stop();
    });
    // The web page and MQTT, where the configuration or the options say.
    firmware::BoxNetwork network({loop, cycle, console.commands, config.settings().web,
                                  config.settings().mqtt, *box.data, *box.clock, network_of(box),
                                  log_book, news, log, calbox::build_version(), unix_now_s});
    on_log = [&network] { network.logged(); };
    // Lines logged while the rest comes down go to standard error only.
    const struct Quiet {
        std::function<void()>& on_log;
        ~Quiet() { on_log = nullptr; }
    } quiet{on_log};
    firmware::CycleSubscription operator_news;
    if (options.operator_acts) {
        operator_news = cycle.subscribe({[&](firmware::Prompt prompt, int step) {
                                             firmware::act_on_prompt(
                                                 *sim_board->bench, *sim_board->lines, prompt, step,
                                                 options.automatic, !options.operator_hands);
                                         },
                                         {},
                                         {},
                                         {},
                                         {}});
    }
    std::unique_ptr<sim::TwinJudge> judge;
    std::optional<sim::TwinVerdict> before;
    firmware::CycleSubscription one_cycle;
    if (options.automatic) {
        // One cycle, then out (once the controller has the whole result).
        one_cycle = cycle.subscribe({{},
                                     {},
                                     [&](bool) {
                                         if (modbus_roles.idle())
                                             loop.stop();
                                         else
                                             stop_when_written = true;
                                     },
                                     {},
                                     {}});
        // The judge, not the box: the twin's truth before the cycle, for the before/after lines.
        judge = sim::make_twin_judge(*sim_board->bench);
        before = judge->before();
        std::printf("before: %s\n", before->line.c_str());
        std::fflush(stdout);
        sim_board->lines->press(std::chrono::milliseconds(100));
    } else if (!console.wanted) {
        log("waiting for the button (no console)");
    }
    loop.run();
    // systemctl stop (SIGTERM) and Ctrl-C (SIGINT) are how a box is meant to be stopped: a clean
    // stop, status 0, whatever the cycle was doing (cancelled: nothing half-sent stays in flight).
    if (stopped_by != 0) {
        log_line("stopped by signal " + std::to_string(stopped_by) + "; " +
                 box.appliance.link->closing_note());
        // --auto promises 0 only for a goal met: stopped before its verdict, it says so.
        if (options.automatic) {
            log_line("--auto: stopped before the verdict (exit status " +
                     std::to_string(kStoppedBeforeVerdict) + ")");
            return kStoppedBeforeVerdict;
        }
        return 0;
    }
    if (!options.automatic) return 0;
    return judged_run_end(box, *judge, *before);
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
