#include "firmware/app/box_parts.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>

#include "firmware/app/sim_operator.hpp"
#include "firmware/cli/version.hpp"
#include "firmware/console/bed_photo_desk.hpp"
#include "firmware/console/job_desk.hpp"
#include "firmware/console/link_key.hpp"
#include "firmware/console/stock_probe_desk.hpp"
#include "firmware/net/box_network.hpp"
#include "firmware/net/web_password.hpp"
#include "firmware/service/service_watch.hpp"

namespace calbox::cli {
namespace {

// The console's port: --console DEVICE, else the configuration's console.device (on the rpi
// board its file's console UART when neither says one). Null with `reopen` empty: no console.
struct ConsolePort {
    std::unique_ptr<hal::SerialPort> port;
    firmware::ConsoleLink::Reopen reopen;
    bool wanted() const { return port != nullptr || static_cast<bool>(reopen); }
};

ConsolePort open_console_port(const RunningBox& running) {
    const Args& args = running.args;
    const auto& settings = running.config.settings().console;
    std::string device = args.get("--console").value_or(settings.device);
    if (running.options.on_rpi && !args.get("--console") && device == "stdin")
        device = rpi_board_settings(args).console_device;
    ConsolePort console;
    if (device == "pty") {
        auto pty = board::pseudo_terminal();
        const auto link = running.data_dir / "console";
        std::error_code ec;
        std::filesystem::remove(link, ec);
        std::filesystem::create_symlink(pty.path, link, ec);
        running.log("console on " + pty.path + (ec ? "" : " (" + link.string() + ")"));
        console.port = std::move(pty.port);
    } else if (device == "stdin") {
        // Standard input when it is a terminal; /dev/null (as under CI) leaves it off.
        if (::isatty(STDIN_FILENO) == 1) console.port = board::standard_io();
    } else if (!device.empty()) {
        // A UART, often a USB adapter: unplugged and plugged in again, or not there yet at the
        // start, it is opened again when it is back.
        console.reopen = [device, baud = settings.baud] {
            return board::serial_port(device, baud);
        };
        // A path that is there but cannot be opened (not a serial device, no permission) is a
        // set-up mistake that waiting does not mend: it stops the box with its reason.
        std::error_code ec;
        if (std::filesystem::exists(device, ec)) {
            console.port = console.reopen();
            running.log("console on " + device);
        } else {
            running.log.warning("console: " + device + " is not there (opened when it is)");
        }
    }
    return console;
}

// The sim board's own console rows: press, hold, quit.
std::vector<firmware::ConsoleCommand> sim_board_commands(sim::SimBoard& board,
                                                         firmware::EventLoop& loop) {
    using Words = std::vector<std::string>;
    return {{"press", "press", "the sim board: a short press of the button",
             [&board](const Words& words, std::string_view, firmware::ConsoleReply& r) {
                 firmware::need_words(words, 1, "press");
                 board.lines->press(std::chrono::milliseconds(100));
                 r.text = "pressed";
             },
             /*acts=*/true},
            {"hold", "hold", "the sim board: a long press of the button",
             [&board](const Words& words, std::string_view, firmware::ConsoleReply& r) {
                 firmware::need_words(words, 1, "hold");
                 board.lines->press(std::chrono::milliseconds(2000));
                 r.text = "held";
             },
             /*acts=*/true},
            {"quit", "quit", "the sim board: stop the box",
             [&loop](const Words& words, std::string_view, firmware::ConsoleReply& r) {
                 firmware::need_words(words, 1, "quit");
                 loop.stop();
                 r.text = "stopping";
             },
             /*acts=*/true}};
}

std::int64_t unix_now_s() {
    return static_cast<std::int64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                         std::chrono::system_clock::now().time_since_epoch())
                                         .count());
}

std::string utc_now_text() {
    return firmware::utc_text(unix_now_s());
}

std::filesystem::path directory_of(const std::filesystem::path& file) {
    return file.parent_path().empty() ? std::filesystem::path(".") : file.parent_path();
}

// The console and the parts with rows of their own on it (the web page's password, the job
// desk, the bed photo, OctoPrint's key, the sim board's button), read on its port; it tells the
// console what the cycle's prompts and notices say.
class BoxConsole final : public BoxPart {
  public:
    explicit BoxConsole(RunningBox& running)
        : port_(open_console_port(running)),
          config_home_(board::data_directory(directory_of(running.config_path))),
          link_key_(
              running.box.loop, running.box.board.machine.link, running.box.network().http(),
              [key_file = running.box.board.machine.link.key_file] {
                  return board::data_directory(directory_of(key_file));
              },
              logged_notice(running.log)),
          job_desk_(running.box.loop, running.box.cycle, *running.box.appliance.link,
                    *running.box.data, utc_now_text, logged_notice(running.log)),
          bed_photo_desk_(running.box.loop, running.box.cycle, *running.box.data,
                          logged_notice(running.log)),
          stock_probe_desk_(running.box.cycle, *running.box.appliance.link, *running.box.data,
                            logged_notice(running.log)),
          commands_(firmware::ConsoleContext{
              running.box.cycle, running.config, *config_home_,
              running.config_path.filename().string(), *running.box.data, running.log_book,
              calbox::build_version(), running.config_changed, rows(running)}) {
        running.console = &commands_;
        running.console_wanted = port_.wanted();
        if (port_.wanted()) {
            link_.emplace(running.box.loop, std::move(port_.port), commands_, running.log,
                          std::move(port_.reopen), running.box.clock.get());
        }
        listening_ = running.box.cycle.subscribe({[this](firmware::Prompt prompt, int) {
                                                      if (prompt != firmware::Prompt::none)
                                                          notice(std::string("waiting: ") +
                                                                 firmware::prompt_text(prompt));
                                                  },
                                                  {},
                                                  {},
                                                  [this](const std::string& line) { notice(line); },
                                                  {}});
    }

  private:
    void notice(const std::string& line) {
        if (link_) link_->notice(line);
    }
    std::function<void(const std::string&)> logged_notice(const firmware::Cycle::Log& log) {
        return [this, log](const std::string& line) {
            log(line);
            notice(line);
        };
    }
    std::vector<firmware::ConsoleCommand> rows(RunningBox& running) {
        std::vector<firmware::ConsoleCommand> more = {
            firmware::web_password_row(running.config, running.box.network().passwords(),
                                       running.config_changed),
            job_desk_.command(),
            job_desk_.zero_command(),
            bed_photo_desk_.command(),
            stock_probe_desk_.command(),
            link_key_.command()};
        if (running.box.board.sim) {
            for (auto& row : sim_board_commands(*running.box.board.sim, running.box.loop))
                more.push_back(std::move(row));
        }
        return more;
    }

    ConsolePort port_;  // opened first, handed to the link once the commands are there
    std::unique_ptr<hal::Storage> config_home_;
    std::optional<firmware::ConsoleLink> link_;
    firmware::LinkKeyRequest link_key_;
    firmware::JobDesk job_desk_;  // jobs compensated through the correction the box keeps
    firmware::BedPhotoDesk bed_photo_desk_;      // the bed now, in the machine's coordinates
    firmware::StockProbeDesk stock_probe_desk_;  // the stock's top by the machine's probe
    firmware::Console commands_;
    firmware::CycleSubscription listening_;
};

// The box's Modbus roles where the configuration or the options say: the PLC map it serves
// (listening to the cycle itself), and the controller it writes each completed cycle's result
// to.
class ModbusRoles final : public BoxPart {
  public:
    explicit ModbusRoles(RunningBox& running) {
        const auto& modbus = running.modbus;
        auto& loop = running.box.loop;
        auto& cycle = running.box.cycle;
        if (modbus.server) {
            namespace plc_map = firmware::plc;
            server_ = board::register_server(*modbus.server,
                                             {plc_map::kCoilCount, plc_map::kDiscreteInputCount, 0,
                                              firmware::input_register_count()},
                                             modbus.timeouts, board::log_to_standard_error);
            plc_.emplace(*server_.server, cycle, modbus.word_order, board::log_to_standard_error);
            loop.watch(server_.server->written_fd(), [this] { plc_->on_coils_written(); });
            board::log_to_standard_error(hal::LogLevel::info,
                                         modbus.server->describe() + ": serving the PLC map" +
                                             (modbus.server->kind == net::ModbusEndpoint::Kind::tcp
                                                  ? " on port " + std::to_string(server_.port)
                                                  : std::string()));
        }
        if (!modbus.client) return;
        client_ = board::register_client(*modbus.client, modbus.timeouts);
        writer_.emplace(*client_, *running.result_map, modbus.word_order,
                        board::log_to_standard_error);
        loop.watch(client_->completion_fd(), [this, &running] {
            writer_->on_completion();
            if (writer_->idle()) running.part_settled();
        });
        running.settled.emplace_back([this] { return writer_->idle(); });
        results_written_for_ = cycle.cycles_completed();
        listening_ = cycle.subscribe(
            {{},
             {},
             [this, &cycle](bool) {
                 if (cycle.cycles_completed() <= results_written_for_) return;
                 results_written_for_ = cycle.cycles_completed();
                 writer_->write(cycle.report(), cycle.mode().result(cycle.report().applied));
             },
             {},
             {}});
    }

  private:
    board::RegisterServer server_;
    std::optional<firmware::PlcServer> plc_;
    std::unique_ptr<hal::RegisterLink> client_;
    std::optional<firmware::ResultWriter> writer_;
    int results_written_for_ = 0;
    firmware::CycleSubscription listening_;
};

// The web page and MQTT, where the configuration (or --web / --mqtt) says; they show the log.
class NetworkPart final : public BoxPart {
  public:
    explicit NetworkPart(RunningBox& running)
        : on_log_(running.on_log),
          network_({running.box.loop, running.box.cycle, *running.console,
                    running.config.settings().web, running.config.settings().mqtt,
                    *running.box.data, running.data_dir.string(), *running.box.clock,
                    running.box.network(), running.log_book, running.news, running.log,
                    calbox::build_version(), unix_now_s}) {
        on_log_ = [this] { network_.logged(); };
    }
    // Lines logged while the rest comes down go to standard error only.
    ~NetworkPart() override { on_log_ = nullptr; }
    NetworkPart(const NetworkPart&) = delete;
    NetworkPart& operator=(const NetworkPart&) = delete;

  private:
    std::function<void()>& on_log_;
    firmware::BoxNetwork network_;
};

// The sim board's person, doing what each prompt asks (--auto, --operator, --operator-hands).
class SimOperator final : public BoxPart {
  public:
    explicit SimOperator(RunningBox& running) {
        const RunOptions& options = running.options;
        sim::SimBoard& board = *running.box.board.sim;
        listening_ = running.box.cycle.subscribe(
            {[&board, &options](firmware::Prompt prompt, int step) {
                 firmware::act_on_prompt(*board.bench, *board.lines, prompt, step,
                                         options.automatic, !options.operator_hands);
             },
             {},
             {},
             {},
             {}});
    }

  private:
    firmware::CycleSubscription listening_;
};

// The box under its service manager (systemd on a board; nobody when run from a shell): last to
// start, so that "ready" means every part is up, and first to stop, saying so.
class ServicePart final : public BoxPart {
  public:
    explicit ServicePart(RunningBox& running)
        : supervisor_(board::service_supervisor()),
          watch_(running.box.loop, *running.box.clock, running.box.cycle, *supervisor_,
                 running.log) {}

  private:
    std::unique_ptr<hal::Supervisor> supervisor_;
    firmware::ServiceWatch watch_;
};

template <class Part>
std::unique_ptr<BoxPart> start(RunningBox& running) {
    return std::make_unique<Part>(running);
}

std::unique_ptr<BoxPart> start_operator(RunningBox& running) {
    if (!running.options.operator_acts) return nullptr;
    return std::make_unique<SimOperator>(running);
}

const std::array<PartStarter, 5> kParts = {{
    {"console", start<BoxConsole>},
    {"modbus", start<ModbusRoles>},
    {"network", start<NetworkPart>},
    {"operator", start_operator},
    {"service", start<ServicePart>},
}};

}  // namespace

bool RunningBox::all_settled() const {
    return std::all_of(settled.begin(), settled.end(), [](const auto& done) { return done(); });
}

void RunningBox::part_settled() {
    if (stop_when_settled && all_settled()) box.loop.stop();
}

std::span<const PartStarter> box_parts() {
    return kParts;
}

void StartedParts::start_all(RunningBox& running) {
    for (const auto& part : box_parts())
        if (auto started = part.start(running)) parts_.push_back(std::move(started));
}

StartedParts::~StartedParts() {
    while (!parts_.empty()) parts_.pop_back();
}

}  // namespace calbox::cli
