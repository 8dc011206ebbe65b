#include "firmware/net/box_news.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string_view>

namespace calbox::firmware {
namespace {

using json = nlohmann::json;

json figures_json(const std::optional<modes::ErrorFigures>& f) {
    if (!f) return nullptr;
    json j = {{"rms_mm", f->rms_mm}, {"max_mm", f->max_mm}};
    j["mean_mm"] = f->mean_mm ? json(*f->mean_mm) : json(nullptr);
    return j;
}

std::optional<modes::ErrorFigures> figures_of(const json& j) {
    if (j.is_null()) return std::nullopt;
    modes::ErrorFigures f;
    f.rms_mm = j.at("rms_mm").get<double>();
    f.max_mm = j.at("max_mm").get<double>();
    if (!j.at("mean_mm").is_null()) f.mean_mm = j.at("mean_mm").get<double>();
    return f;
}

json entry_json(const HistoryEntry& e) {
    return {{"cycle", e.cycle},
            {"mode", e.mode},
            {"finished", utc_text(e.finished_unix_s)},
            {"finished_unix_s", e.finished_unix_s},
            {"result", e.result},
            {"before", figures_json(e.before)},
            {"in_force", figures_json(e.in_force)},
            {"after", figures_json(e.after)},
            {"seconds", e.seconds}};
}

HistoryEntry entry_of(const json& j) {
    HistoryEntry e;
    e.cycle = j.at("cycle").get<int>();
    e.mode = j.at("mode").get<std::string>();
    e.finished_unix_s = j.at("finished_unix_s").get<std::int64_t>();
    e.result = j.at("result").get<std::string>();
    e.before = figures_of(j.at("before"));
    // A history written before the box kept the figure: the error before stood for it.
    e.in_force = j.contains("in_force") ? figures_of(j.at("in_force")) : e.before;
    e.after = figures_of(j.at("after"));
    e.seconds = j.at("seconds").get<double>();
    return e;
}

// A label's value as the text format escapes it.
std::string label_value(const std::string& text) {
    std::string out;
    for (const char c : text) {
        if (c == '\\' || c == '"') out += '\\';
        if (c == '\n') {
            out += "\\n";
            continue;
        }
        out += c;
    }
    return out;
}

// Go's %g-like shortest form Prometheus' parsers read; never "nan" or "inf" spelled otherwise.
std::string sample_value(double v) {
    if (std::isnan(v)) return "NaN";
    if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
    std::ostringstream out;
    out.precision(10);
    out << v;
    return out.str();
}

void family(std::ostringstream& out, const std::string& name, const std::string& type,
            const std::string& help) {
    out << "# HELP " << name << ' ' << help << "\n# TYPE " << name << ' ' << type << '\n';
}

// Cycles counted by (mode, result), one sample each.
void by_mode_and_result(std::ostringstream& out, const std::string& name,
                        const std::map<std::pair<std::string, std::string>, int>& counts) {
    for (const auto& [key, count] : counts)
        out << name << "{mode=\"" << label_value(key.first) << "\",result=\"" << key.second
            << "\"} " << count << '\n';
}

// When the newest cycle with one of `results` finished.
std::optional<std::int64_t> last_finished(const std::vector<HistoryEntry>& history,
                                          std::initializer_list<std::string_view> results) {
    for (auto it = history.rbegin(); it != history.rend(); ++it)
        if (std::find(results.begin(), results.end(), it->result) != results.end())
            return it->finished_unix_s;
    return std::nullopt;
}

}  // namespace

bool operator==(const HistoryEntry& a, const HistoryEntry& b) {
    return entry_json(a) == entry_json(b);
}

double headline_mm(const modes::ErrorFigures& figures) {
    return figures.mean_mm.value_or(figures.rms_mm);
}

std::string utc_text(std::int64_t unix_s) {
    const auto t = static_cast<std::time_t>(unix_s);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char text[32];
    std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm);
    return text;
}

BoxNews::BoxNews(hal::Storage& data, std::string version,
                 const std::function<void(const std::string&)>& problem)
    : data_(data), version_(std::move(version)) {
    const auto text = data_.read_file(kHistoryFile);
    if (!text) return;
    try {
        const json kept = json::parse(*text);  // named: a range over a temporary's member dangles
        for (const auto& j : kept.at("cycles")) history_.push_back(entry_of(j));
    } catch (const std::exception& e) {
        history_.clear();
        const std::string aside = std::string(kHistoryFile) + ".damaged";
        try {
            data_.replace_file(aside, *text);
            data_.remove_file(kHistoryFile);
        } catch (const std::runtime_error&) {
            // Kept where it is: the next cycle's write replaces it, the damage already told.
        }
        if (problem)
            problem(std::string(kHistoryFile) + " does not parse (" + e.what() +
                    "): set aside as " + aside + ", a new history begun");
    }
}

std::string BoxNews::cycle_ended(const Cycle& cycle, bool completed, std::int64_t now_unix_s) {
    const CycleReport& report = cycle.report();
    HistoryEntry e;
    e.cycle = report.number;
    e.mode = cycle.mode().goal().mode;
    e.finished_unix_s = now_unix_s;
    e.result = completed                            ? (report.applied ? "applied" : "unchanged")
               : cycle.state() == CycleState::error ? "failed"
                                                    : "cancelled";
    e.before = report.measured;
    e.in_force = report.in_force;
    e.after = report.verified;
    e.seconds = report.box_seconds + report.camera_seconds + report.machine_seconds;
    return add(std::move(e));
}

std::string BoxNews::add(HistoryEntry e) {
    ++cycles_[{e.mode, e.result}];
    history_.push_back(std::move(e));
    if (history_.size() > kHistoryKept)
        history_.erase(history_.begin(), history_.begin() + static_cast<std::ptrdiff_t>(
                                                                history_.size() - kHistoryKept));
    try {
        data_.replace_file(kHistoryFile, history_json().dump(1) + "\n");
    } catch (const std::runtime_error& err) {
        return std::string(kHistoryFile) + " not written: " + err.what();
    }
    return {};
}

std::optional<double> BoxNews::drift_mm() const {
    for (auto last = history_.rbegin(); last != history_.rend(); ++last) {
        if (!last->in_force) continue;
        for (auto it = std::next(last); it != history_.rend(); ++it)
            if (it->result == "applied" && it->after)
                return headline_mm(*last->in_force) - headline_mm(*it->after);
        return std::nullopt;
    }
    return std::nullopt;
}

std::optional<std::int64_t> BoxNews::last_calibrated_unix_s() const {
    return last_finished(history_, {"applied"});
}

std::optional<std::int64_t> BoxNews::last_completed_unix_s() const {
    return last_finished(history_, {"applied", "unchanged"});
}

std::optional<bool> BoxNews::needs_calibration() const {
    for (auto it = history_.rbegin(); it != history_.rend(); ++it)
        if (it->in_force) return headline_mm(*it->in_force) > needs_calibration_mm_;
    return std::nullopt;
}

json BoxNews::history_json(std::size_t last) const {
    json cycles = json::array();
    const std::size_t first = history_.size() > last ? history_.size() - last : 0;
    for (std::size_t k = first; k < history_.size(); ++k) cycles.push_back(entry_json(history_[k]));
    return {{"cycles", cycles}};
}

json BoxNews::status(const Cycle& cycle) const {
    json j = {{"state", state_name(cycle.state())},
              {"waiting", prompt_text(cycle.prompt())},
              {"cycle", cycle.report().number},
              {"completed", cycle.cycles_completed()},
              {"error", cycle.error()},
              {"setup_coverage", cycle.setup_coverage()},
              {"mode", cycle.mode().goal().mode},
              {"needs_calibration_mm", needs_calibration_mm_}};
    j["last"] = history_.empty() ? json(nullptr) : entry_json(history_.back());
    const auto drift = drift_mm();
    j["drift_mm"] = drift ? json(*drift) : json(nullptr);
    const auto calibrated = last_calibrated_unix_s();
    j["last_calibrated"] = calibrated ? json(utc_text(*calibrated)) : json(nullptr);
    const auto needs = needs_calibration();
    j["needs_calibration"] = needs ? json(*needs) : json(nullptr);
    return j;
}

std::string BoxNews::metrics(const Cycle& cycle) const {
    return metrics(cycle.state(), cycle.report());
}

std::string BoxNews::metrics(CycleState now, const CycleReport& report) const {
    std::ostringstream out;
    family(out, "calbox_build_info", "gauge", "The firmware's version, as a label; always 1.");
    out << "calbox_build_info{version=\"" << label_value(version_) << "\"} 1\n";
    family(out, "calbox_state", "gauge", "The cycle's state: 1 for the one it is in.");
    for (int s = 0; s <= static_cast<int>(CycleState::error); ++s) {
        const auto state = static_cast<CycleState>(s);
        out << "calbox_state{state=\"" << state_name(state) << "\"} " << (state == now ? 1 : 0)
            << '\n';
    }
    family(out, "calbox_cycles_total", "counter",
           "Calibration cycles ended since the box started, by mode and result.");
    by_mode_and_result(out, "calbox_cycles_total", cycles_);
    // The kept history's, which a restart does not reset (a farm's cycles by result).
    family(out, "calbox_history_cycles", "gauge",
           "Cycles in the box's kept drift history (its last 1000), by mode and result.");
    std::map<std::pair<std::string, std::string>, int> kept;
    for (const auto& e : history_) ++kept[{e.mode, e.result}];
    by_mode_and_result(out, "calbox_history_cycles", kept);
    const HistoryEntry* last = history_.empty() ? nullptr : &history_.back();
    family(out, "calbox_last_error_metres", "gauge",
           "The last cycle's error: measured before its correction, verified after it.");
    if (last != nullptr) {
        const auto figures = [&](const char* stage, const std::optional<modes::ErrorFigures>& f) {
            if (!f) return;
            const std::string labels = std::string("{stage=\"") + stage + "\",figure=\"";
            if (f->mean_mm)
                out << "calbox_last_error_metres" << labels << "mean\"} "
                    << sample_value(*f->mean_mm / 1000) << '\n';
            out << "calbox_last_error_metres" << labels << "rms\"} "
                << sample_value(f->rms_mm / 1000) << '\n';
            out << "calbox_last_error_metres" << labels << "max\"} "
                << sample_value(f->max_mm / 1000) << '\n';
        };
        figures("before", last->before);
        figures("after", last->after);
    }
    family(out, "calbox_last_cycle_duration_seconds", "gauge",
           "The last cycle's time by part: the box's own work, the camera, the machine.");
    if (report.number > 0) {
        out << "calbox_last_cycle_duration_seconds{part=\"box\"} "
            << sample_value(report.box_seconds) << '\n'
            << "calbox_last_cycle_duration_seconds{part=\"camera\"} "
            << sample_value(report.camera_seconds) << '\n'
            << "calbox_last_cycle_duration_seconds{part=\"machine\"} "
            << sample_value(report.machine_seconds) << '\n';
    }
    family(out, "calbox_drift_metres", "gauge",
           "The last error in force (through the kept correction, for a galvo or a router) less "
           "the one verified after the last calibration.");
    if (const auto drift = drift_mm())
        out << "calbox_drift_metres " << sample_value(*drift / 1000) << '\n';
    family(out, "calbox_last_calibration_timestamp_seconds", "gauge",
           "When the last correction was applied, in Unix time.");
    if (const auto t = last_calibrated_unix_s())
        out << "calbox_last_calibration_timestamp_seconds " << *t << '\n';
    family(out, "calbox_last_completed_cycle_timestamp_seconds", "gauge",
           "When the last cycle completed (a correction applied, or the machine within its "
           "tolerance), in Unix time.");
    if (const auto t = last_completed_unix_s())
        out << "calbox_last_completed_cycle_timestamp_seconds " << *t << '\n';
    family(out, "calbox_needs_calibration", "gauge",
           "1 when the last cycle's error in force (through the kept correction, for a galvo or a "
           "router) exceeded the configured limit.");
    if (const auto needs = needs_calibration())
        out << "calbox_needs_calibration " << (*needs ? 1 : 0) << '\n';
    return out.str();
}

}  // namespace calbox::firmware
