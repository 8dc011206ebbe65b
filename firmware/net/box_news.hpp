#pragma once
// What the box tells the network, as the display tells the person beside it: the status, each
// cycle's figures kept as the machine's drift history (DATA/history.json), the counters since the
// start, and /metrics in Prometheus' text format. A consumer of the cycle's events; it lives on
// the loop's thread and never drives the cycle.
#include <array>
#include <cstdint>
#include <map>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/modes/goal.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/settings/settings_table.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

// One cycle's line in the drift history.
struct HistoryEntry {
    int cycle = 0;
    std::string mode;  // "delta", "galvo", "planar"
    std::int64_t finished_unix_s = 0;
    // applied | unchanged (completed, nothing sent) | cancelled | failed
    std::string result;
    std::optional<modes::ErrorFigures> before, after;  // measured, verified
    // The machine's error as jobs met it before the cycle (CycleReport::in_force): `before`
    // through the correction the box keeps, for a mode that keeps one.
    std::optional<modes::ErrorFigures> in_force;
    double seconds = 0;  // the box's, the camera's and the machine's
};
bool operator==(const HistoryEntry& a, const HistoryEntry& b);

// The figure a mode's goal is about: the mean where the mode measures one (planar, galvo), else
// the RMS (a delta's placement).
double headline_mm(const modes::ErrorFigures& figures);

// "2026-11-26T03:25:33Z".
std::string utc_text(std::int64_t unix_s);

// When the box says the machine needs calibrating (the page, MQTT, /metrics).
struct ReportSettings {
    // A cycle's error as jobs met it (CycleReport::in_force) past this.
    double needs_calibration_mm = 0.05;
};

// The report's table of the configuration: [report].
SettingsTable<ReportSettings> report_settings_table();

class BoxNews {
  public:
    static constexpr const char* kHistoryFile = "history.json";
    static constexpr std::size_t kHistoryKept = 1000;
    // Reads the history kept in `data`; a file that does not parse is set aside (renamed
    // history.json.damaged, said through `problem`) rather than stopping the box.
    BoxNews(hal::Storage& data, std::string version,
            const std::function<void(const std::string&)>& problem);

    // A cycle ended (Cycle::on_cycle_end): its line added to the history (and the file; a
    // failed write is returned as the reason, the line still kept in memory), the counters.
    std::string cycle_ended(const Cycle& cycle, bool completed, std::int64_t now_unix_s);
    // One line added as cycle_ended adds it (its result counted, the file written).
    std::string add(HistoryEntry entry);
    void set_needs_calibration_mm(double limit_mm) { needs_calibration_mm_ = limit_mm; }

    const std::vector<HistoryEntry>& history() const { return history_; }
    // The last entry's error as jobs met it (in_force) less the verified after of the last
    // calibration before it, both the error through the correction then in force: how far the
    // machine drifted since it was calibrated. None until both exist.
    std::optional<double> drift_mm() const;
    std::optional<std::int64_t> last_calibrated_unix_s() const;
    // The last cycle that completed, a correction applied or the machine found within its
    // tolerance (a farm's "no successful cycle for N days").
    std::optional<std::int64_t> last_completed_unix_s() const;
    // The last cycle's error as jobs met it (in_force) exceeded the limit (none: no cycle
    // measured yet).
    std::optional<bool> needs_calibration() const;

    // {"state","waiting","cycle","completed","error","setup_coverage","mode","last":{...},
    //  "drift_mm","last_calibrated","needs_calibration","history":[...]}
    nlohmann::json status(const Cycle& cycle) const;
    // {"cycles": [...]}: every line kept, or only the newest `last`.
    nlohmann::json history_json(std::size_t last = kHistoryKept) const;
    // Prometheus' text exposition format 0.0.4: base units (metres, seconds), counters _total.
    std::string metrics(const Cycle& cycle) const;
    std::string metrics(CycleState state, const CycleReport& last_report) const;

  private:
    hal::Storage& data_;
    std::string version_;
    std::vector<HistoryEntry> history_;
    std::map<std::pair<std::string, std::string>, int> cycles_;  // (mode, result) since start
    double needs_calibration_mm_ = ReportSettings{}.needs_calibration_mm;
};

}  // namespace calbox::firmware
