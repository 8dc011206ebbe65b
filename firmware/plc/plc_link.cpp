#include "firmware/plc/plc_link.hpp"

#include <toml++/toml.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "core/models/toml_reader.hpp"
#include "firmware/cycle/cycle_mode.hpp"

namespace calbox::firmware {
namespace {

constexpr double kAbsent = std::numeric_limits<double>::quiet_NaN();

void place_tables_at_defaults(ResultRegisterMap& map) {
    for (const auto& table : mode_tables()) map.table_registers[table.key] = table.default_register;
}

const ModeTable* table_of_key(const std::string& key) {
    static const std::vector<ModeTable> tables = mode_tables();
    for (const auto& table : tables)
        if (table.key == key) return &table;
    return nullptr;
}

void append_float(std::vector<std::uint16_t>& words, double value, models::WordOrder order) {
    const auto w = models::pack_float(static_cast<float>(value), order);
    words.push_back(w[0]);
    words.push_back(w[1]);
}

// A value's two registers may not fall inside a table's block.
void refuse_values_over_tables(const ResultRegisterMap& map, const std::string& source) {
    for (const auto& [key, first] : map.table_registers) {
        const auto* table = table_of_key(key);
        for (const auto& [name, address] : map.registers)
            if (address + 1 >= first && address < first + table->registers)
                throw std::runtime_error(std::string(source)
                                             .append(": ")
                                             .append(name)
                                             .append(" overlaps ")
                                             .append(table->what)
                                             .append(" at register ")
                                             .append(std::to_string(first)));
    }
}

}  // namespace

const std::vector<std::string>& result_value_names() {
    static const std::vector<std::string> names = [] {
        // The figures every cycle has (a mode may predict; the delta does), in the block's
        // documented order, then the modes' own values.
        std::vector<std::string> n{"measured_xy_rms_mm",  "measured_xy_max_mm",
                                   "predicted_xy_rms_mm", "predicted_xy_max_mm",
                                   "verified_xy_rms_mm",  "verified_xy_max_mm"};
        for (auto& name : mode_result_names()) n.push_back(std::move(name));
        return n;
    }();
    return names;
}

std::vector<std::pair<std::string, double>> result_values(const CycleReport& r,
                                                          const ModeResult& mode) {
    std::map<std::string, double> known;
    if (r.measured) {
        known["measured_xy_rms_mm"] = r.measured->rms_mm;
        known["measured_xy_max_mm"] = r.measured->max_mm;
    }
    if (r.verified) {
        known["verified_xy_rms_mm"] = r.verified->rms_mm;
        known["verified_xy_max_mm"] = r.verified->max_mm;
    }
    for (const auto& [name, value] : mode.values) known[name] = value;
    std::vector<std::pair<std::string, double>> values;
    for (const auto& name : result_value_names()) {
        const auto at = known.find(name);
        values.emplace_back(name, at == known.end() ? kAbsent : at->second);
    }
    return values;
}

int input_register_count() {
    return plc::kResultBlockRegister + 2 * static_cast<int>(result_value_names().size());
}

PlcServer::PlcServer(hal::RegisterServer& server, Cycle& cycle, models::WordOrder order, Log log)
    : server_(server),
      cycle_(cycle),
      order_(order),
      log_(std::move(log)),
      completed_at_start_(cycle.cycles_completed()) {
    publish();
    listening_ = cycle_.subscribe({[this](Prompt, int) { publish(); },
                                   [this](CycleState) { publish(); },
                                   [this](bool) { publish(); },
                                   {},
                                   {}});
}

void PlcServer::publish() {
    const CycleState state = cycle_.state();
    const bool idle = state == CycleState::idle;
    if (was_idle_ && !idle) completed_at_start_ = cycle_.cycles_completed();
    was_idle_ = idle;
    const bool done = idle && cycle_.cycles_completed() > completed_at_start_;
    const auto& report = cycle_.report();
    // Each mode's own goal, on the box's own verification.
    const bool pass = done && cycle_.goal_met();
    const Prompt prompt = cycle_.prompt();
    const bool error = state == CycleState::error;
    std::vector<bool> inputs(plc::kDiscreteInputCount, false);
    inputs[plc::kReadyInput] = idle;
    inputs[plc::kBusyInput] = !idle && !error;
    inputs[plc::kReviewInput] = prompt == Prompt::review;
    inputs[plc::kDoneInput] = done;
    inputs[plc::kPassInput] = pass;
    inputs[plc::kErrorInput] = error;
    inputs[plc::kPersonInput] = prompt == Prompt::hold_calibration_board ||
                                prompt == Prompt::lay_plane_board || prompt == Prompt::clear_bed;

    // The result block changes only when a cycle completes, so a PLC reading it after done
    // never sees half of the next cycle.
    if (done && published_results_ != cycle_.cycles_completed()) {
        std::vector<std::uint16_t> block;
        for (const auto& [name, value] :
             result_values(report, cycle_.mode().result(report.applied))) {
            append_float(block, value, order_);
        }
        server_.set_input_registers(plc::kResultBlockRegister, block);
        published_results_ = cycle_.cycles_completed();
    }
    const std::array<std::uint16_t, 4> head{
        static_cast<std::uint16_t>(state),
        static_cast<std::uint16_t>(error ? static_cast<int>(cycle_.failed_in()) : 0),
        static_cast<std::uint16_t>(cycle_.cycles_completed() & 0xFFFF),
        static_cast<std::uint16_t>(order_)};
    server_.set_input_registers(plc::kStateRegister, head);
    // The status bits last: when done reads 1, the counter and the block are already there.
    server_.set_discrete_inputs(0, inputs);
}

void PlcServer::on_coils_written() {
    for (const int coil : server_.take_coils_set()) {
        switch (coil) {
            case plc::kTriggerCoil:
                if (cycle_.state() == CycleState::idle) {
                    cycle_.start();
                } else {
                    log_.warning("modbus: trigger ignored: the box is " +
                                 std::string(state_name(cycle_.state())));
                }
                break;
            case plc::kConfirmCoil:
                if (cycle_.prompt() == Prompt::review) {
                    cycle_.press(false);
                } else {
                    log_.warning("modbus: confirm ignored: nothing is waiting for review");
                }
                break;
            case plc::kCancelCoil:
                cycle_.cancel("cancelled over Modbus");
                break;
            case plc::kAcknowledgeCoil:
                cycle_.acknowledge();
                break;
            default:
                break;
        }
    }
    publish();
}

ResultRegisterMap ResultRegisterMap::whole_block(int first_register) {
    ResultRegisterMap map;
    place_tables_at_defaults(map);
    int address = first_register;
    for (const auto& name : result_value_names()) {
        map.registers.emplace_back(name, address);
        address += 2;
    }
    return map;
}

ResultRegisterMap ResultRegisterMap::from_toml(const std::string& text, const std::string& source) {
    const toml::table table = models::parse_toml(text, source);
    std::map<std::string, bool> known;
    for (const auto& name : result_value_names()) known[name] = true;
    ResultRegisterMap map;
    place_tables_at_defaults(map);
    std::map<int, std::string> taken;  // register -> the value using it
    for (const auto& [key, node] : table) {
        const std::string name(key.str());
        std::string at = source;
        at.append(":").append(std::to_string(node.source().begin.line)).append(": ");
        const auto* table = table_of_key(name);
        if (known.count(name) == 0 && table == nullptr)
            throw std::runtime_error(at.append("'").append(name).append("' is not a result value"));
        const auto address = node.value<std::int64_t>();
        if (table != nullptr) {
            if (!node.is_integer() || !address || *address < 0 ||
                *address > 65535 - table->registers)
                throw std::runtime_error(at + name + ": a holding register 0 to " +
                                         std::to_string(65535 - table->registers) +
                                         " (the table takes " + std::to_string(table->registers) +
                                         " registers)");
            map.table_registers[name] = static_cast<int>(*address);
            continue;
        }
        if (!node.is_integer() || !address || *address < 0 || *address > 65534) {
            throw std::runtime_error(at + name + ": a holding register 0 to 65534");
        }
        for (int r = static_cast<int>(*address); r <= *address + 1; ++r) {
            if (taken.count(r) != 0) {
                throw std::runtime_error(at + name + ": register " + std::to_string(r) +
                                         " is already " + taken[r] + "'s");
            }
            taken[r] = name;
        }
        map.registers.emplace_back(name, static_cast<int>(*address));
    }
    if (map.registers.empty()) throw std::runtime_error(source + ": maps no result value");
    refuse_values_over_tables(map, source);
    return map;
}

ResultWriter::ResultWriter(hal::RegisterLink& link, ResultRegisterMap map, models::WordOrder order,
                           Log log)
    : link_(link), map_(std::move(map)), order_(order), log_(std::move(log)) {}

void ResultWriter::write(const CycleReport& report, const ModeResult& mode) {
    std::map<std::string, double> values;
    for (const auto& [name, value] : result_values(report, mode)) values[name] = value;
    std::vector<std::pair<int, std::uint16_t>> words;
    for (const auto& [name, address] : map_.registers) {
        const auto w = models::pack_float(static_cast<float>(values.at(name)), order_);
        words.emplace_back(address, w[0]);
        words.emplace_back(address + 1, w[1]);
    }
    // A correction table the box keeps, for a controller that reads it from its registers.
    int address = mode.table.empty() ? 0 : map_.table_registers.at(mode.table_key);
    for (const float f : mode.table) {
        const auto w = models::pack_float(f, order_);
        words.emplace_back(address++, w[0]);
        words.emplace_back(address++, w[1]);
    }
    queue_words(std::move(words));
    if (!in_flight_) next();
}

void ResultWriter::queue_words(std::vector<std::pair<int, std::uint16_t>> words) {
    std::sort(words.begin(), words.end());
    // Contiguous registers go in one request (at most 123, the protocol's limit).
    for (const auto& [address, word] : words) {
        if (queue_.empty() ||
            queue_.back().first + static_cast<int>(queue_.back().second.size()) != address ||
            queue_.back().second.size() >= 123) {
            queue_.push_back({address, {}});
        }
        queue_.back().second.push_back(word);
    }
}

void ResultWriter::next() {
    if (queue_.empty()) return;
    auto [address, block] = std::move(queue_.front());
    queue_.erase(queue_.begin());
    in_flight_ = true;
    link_.start_write_registers(address, std::move(block));
}

void ResultWriter::on_completion() {
    if (!in_flight_) return;
    in_flight_ = false;
    const auto result = link_.take_result();
    if (result.ok()) {
        ++written_;
    } else {
        ++failed_;
        queue_.clear();  // the rest of this result would leave the controller half-written
        log_.error("modbus: the result was not written: " + result.error);
    }
    next();
}

}  // namespace calbox::firmware
