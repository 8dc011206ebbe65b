#pragma once
// The stock's top measured by the router's own touch probe ([touch_probe] in the machine file,
// grbl's G38.2): the console's `probe stock`, on the sheet and on the bed beside it, at points
// given or at the corner of the sheet the last bed photo found. Nothing moves without confirm.
// The height is kept as stock-top.json, which a bed photo without a height of its own takes.
#include <functional>
#include <memory>
#include <string>

#include "firmware/console/console.hpp"
#include "firmware/links/machine_link.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

class Cycle;

// The probed top of the stock on the bed (core/modes/stock_top), kept in the data directory.
constexpr const char* kProbedStockTopFile = "stock-top.json";

class StockProbeDesk {
  public:
    using Notice = std::function<void(const std::string&)>;
    StockProbeDesk(Cycle& cycle, MachineLink& link, hal::Storage& data, Notice notice);
    StockProbeDesk(const StockProbeDesk&) = delete;
    StockProbeDesk& operator=(const StockProbeDesk&) = delete;
    // `probe stock [ON_X,ON_Y BESIDE_X,BESIDE_Y] [confirm]`: without confirm, the lines it would
    // send; with it, sent when the link is free, the height a notice.
    ConsoleCommand command();

  private:
    void probed(const JobOutcome& outcome);
    Cycle& cycle_;
    MachineLink& link_;
    hal::Storage& data_;
    Notice notice_;
    bool busy_ = false;
    struct Sent;
    std::shared_ptr<Sent> sent_;
};

}  // namespace calbox::firmware
