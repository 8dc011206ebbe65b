#pragma once
// The box on Modbus: as a server a PLC drives it the way PLCs drive smart cameras (a trigger
// coil, status bits, a result counter and a result block), and as a client it writes each
// completed cycle's result into a controller's registers. The map below is the one docs/devices.md
// shows; change both together.
#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/models/register_words.hpp"
#include "core/net/endpoints.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/settings/settings_table.hpp"
#include "hal/log.hpp"
#include "hal/register_link.hpp"

namespace calbox::firmware {

// The box's Modbus roles: the PLC map it serves, and the controller it writes each result to.
struct ModbusSettings {
    std::optional<net::ModbusEndpoint> server;  // serve the PLC map
    std::optional<net::ModbusEndpoint> client;  // the controller the results are written to
    std::string client_map;  // a map file (value_name = register); empty: the whole block from 0
    models::WordOrder word_order = models::WordOrder::abcd;
    hal::ModbusTimeouts timeouts;
};

// Modbus's table of the configuration: [modbus].
SettingsTable<ModbusSettings> modbus_settings_table();

namespace plc {
// Coils (function 1 to read, 5 or 15 to write): a client writes 1, the box acts and clears it.
constexpr int kTriggerCoil = 0;      // start a cycle (from idle)
constexpr int kConfirmCoil = 1;      // apply the reviewed correction
constexpr int kCancelCoil = 2;       // cancel the running cycle
constexpr int kAcknowledgeCoil = 3;  // clear an error, back to idle
constexpr int kCoilCount = 4;
// Discrete inputs (function 2).
constexpr int kReadyInput = 0;   // idle: a trigger starts a cycle
constexpr int kBusyInput = 1;    // a cycle or a revert is running
constexpr int kReviewInput = 2;  // waiting for confirm (or cancel)
constexpr int kDoneInput = 3;    // the last cycle completed; cleared when the next starts
constexpr int kPassInput = 4;    // ... and met its mode's goal on its verification
constexpr int kErrorInput = 5;   // stopped on an error; acknowledge to clear
constexpr int kPersonInput = 6;  // waiting for a person at the box (set-up, clear the bed)
constexpr int kDiscreteInputCount = 7;
// Input registers (function 4).
constexpr int kStateRegister = 0;          // the state code (state_name order, idle = 0)
constexpr int kErrorCodeRegister = 1;      // the state code of the stage that stopped; 0: none
constexpr int kResultCounterRegister = 2;  // completed cycles, modulo 65536
constexpr int kWordOrderRegister = 3;      // the floats' order: 0 abcd, 1 cdab, 2 badc, 3 dcba
constexpr int kResultBlockRegister = 4;    // the result values, two registers each
}  // namespace plc

// The result block's value names, in its order.
const std::vector<std::string>& result_value_names();
// A completed cycle's result in the order of the result block; NaN where the cycle has no such
// value (no verification, or a mode without it: a galvo has no rod length).
std::vector<std::pair<std::string, double>> result_values(const CycleReport& report,
                                                          const ModeResult& mode);
int input_register_count();

class PlcServer {
  public:
    using Log = hal::Log;
    // Listens to the cycle: its status bits and registers follow each state, prompt and end.
    PlcServer(hal::RegisterServer& server, Cycle& cycle, models::WordOrder order, Log log);
    void publish();
    // Call when the server's written_fd() is readable: acts on the coils a client set.
    void on_coils_written();

  private:
    hal::RegisterServer& server_;
    Cycle& cycle_;
    models::WordOrder order_;
    Log log_;
    int completed_at_start_;
    bool was_idle_ = true;
    int published_results_ = -1;
    CycleSubscription listening_;  // last: ends before the rest goes
};

// Writes each completed cycle's result block into a controller's holding registers, one value
// (two registers) per mapped name; the default map is the whole block from register 0.
struct ResultRegisterMap {
    std::vector<std::pair<std::string, int>> registers;  // value name -> first holding register
    // The first holding register of each mode's table (mode_tables(): its default unless the
    // file's `key = N` moves it); docs/devices.md, "The table over Modbus".
    std::map<std::string, int> table_registers;
    static ResultRegisterMap whole_block(int first_register);
    // A TOML file of `name = register` lines; unknown names, duplicate or overlapping
    // registers are errors naming the line. Throws std::runtime_error.
    static ResultRegisterMap from_toml(const std::string& text, const std::string& source);
};

class ResultWriter {
  public:
    using Log = hal::Log;
    ResultWriter(hal::RegisterLink& link, ResultRegisterMap map, models::WordOrder order, Log log);
    // Queued behind a write still in flight.
    void write(const CycleReport& report, const ModeResult& mode);
    void on_completion();  // when the link's completion_fd is readable
    bool idle() const { return !in_flight_ && queue_.empty(); }
    int written() const { return written_; }
    int failed() const { return failed_; }

  private:
    void next();
    // Queues (address, word) pairs as requests of contiguous registers (at most 123 each).
    void queue_words(std::vector<std::pair<int, std::uint16_t>> words);
    hal::RegisterLink& link_;
    ResultRegisterMap map_;
    models::WordOrder order_;
    Log log_;
    std::vector<std::pair<int, std::vector<std::uint16_t>>> queue_;
    bool in_flight_ = false;
    int written_ = 0;
    int failed_ = 0;
};

}  // namespace calbox::firmware
