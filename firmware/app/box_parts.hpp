#pragma once
// The parts of a running box beside its cycle, started by `calbox run` from one list (box_parts):
// the console, the Modbus roles, the network's windows, the sim board's operator. Each is made
// from what the box and its configuration hold, subscribes itself to the cycle's news, hands the
// console its own rows, and leaves in RunningBox what the parts after it need. A part that its
// configuration leaves off is not started.
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "firmware/app/box.hpp"
#include "firmware/app/box_config.hpp"
#include "firmware/console/console.hpp"
#include "firmware/net/box_news.hpp"
#include "firmware/plc/plc_link.hpp"

namespace calbox::cli {

// What the parts are started from, and what they leave for those after them and for run().
struct RunningBox {
    const Args& args;
    const RunOptions& options;
    Box& box;
    firmware::BoxConfig& config;
    std::filesystem::path config_path;
    std::filesystem::path data_dir;
    // The configuration's [modbus] with the options over it, and the result map it names (read
    // before the board starts, so that a bad file stops nothing half-open).
    firmware::ModbusSettings modbus;
    std::optional<firmware::ResultRegisterMap> result_map;
    const firmware::LogBook& log_book;
    firmware::BoxNews& news;
    firmware::Cycle::Log log;
    std::function<void()> config_changed;  // puts a changed configuration in force
    std::function<void()>& on_log;         // set by a part that shows the log (the network)

    // Left by the console part: its commands (the network acts only through them), and whether
    // a port was asked for.
    firmware::Console* console = nullptr;
    bool console_wanted = false;
    // Parts with work in flight (a result still being written to a controller): each says
    // whether it is done, and calls `part_settled` when it is.
    std::vector<std::function<bool()>> settled{};
    bool stop_when_settled = false;  // --auto: the cycle is over, the loop stops once all are
    bool all_settled() const;
    void part_settled();
};

// A started part: it keeps its subscriptions and devices until it is destroyed.
class BoxPart {
  public:
    virtual ~BoxPart() = default;
};

struct PartStarter {
    const char* name;
    // Null when the configuration leaves the part off.
    std::unique_ptr<BoxPart> (*start)(RunningBox& running);
};

// In the order they start (and stop in reverse): the console before the network, which acts
// through its commands.
std::span<const PartStarter> box_parts();

// The parts started, stopped in reverse order.
class StartedParts {
  public:
    void start_all(RunningBox& running);
    ~StartedParts();

  private:
    std::vector<std::unique_ptr<BoxPart>> parts_;
};

}  // namespace calbox::cli
