#include "firmware/console/console.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "core/number_text.hpp"

namespace calbox::firmware {
namespace {

using nlohmann::json;

using Refused = ConsoleRefused;

std::vector<std::string> words_of(std::string_view line) {
    std::vector<std::string> words;
    std::istringstream in{std::string(line)};
    std::string w;
    while (in >> w) words.push_back(w);
    return words;
}

// A control byte (a NUL from a line noise burst, an escape sequence) is refused by its place:
// echoed in a reply it would cut the line short at a NUL or act on the terminal.
std::optional<std::string> control_byte_refusal(std::string_view line) {
    const auto at = std::find_if(line.begin(), line.end(), [](char c) {
        const auto u = static_cast<unsigned char>(c);
        return (u < 0x20 && c != '\t') || u == 0x7f;
    });
    if (at == line.end()) return std::nullopt;
    char why[96];
    std::snprintf(why, sizeof why,
                  "control byte 0x%02x at column %zu refused (a command is printable text)",
                  static_cast<unsigned>(static_cast<unsigned char>(*at)),
                  static_cast<std::size_t>(at - line.begin()) + 1);
    return std::string(why);
}

// The row whose name's words begin the line, the longest first ("config set"); throws Refused
// with a group's usage ("config list|get|...") for its first word alone.
const ConsoleCommand& row_for(const std::vector<ConsoleCommand>& table,
                              const std::vector<std::string>& words) {
    const ConsoleCommand* found = nullptr;
    std::size_t found_words = 0;
    std::string group_usage;
    for (const auto& c : table) {
        const auto name = words_of(c.name);
        if (name.size() <= words.size() && name.size() > found_words &&
            std::equal(name.begin(), name.end(), words.begin())) {
            found = &c;
            found_words = name.size();
        }
        if (name.size() > 1 && name[0] == words[0])
            group_usage += (group_usage.empty() ? words[0] + " " : "|") + name[1];
    }
    if (found == nullptr && !group_usage.empty()) throw Refused("usage: " + group_usage);
    if (found == nullptr) throw Refused("'" + words[0] + "' is not a command (help lists them)");
    return *found;
}

}  // namespace

std::string console_words_after(std::string_view line, std::size_t skip) {
    std::size_t at = 0;
    for (std::size_t i = 0; i < skip; ++i) {
        at = line.find_first_not_of(" \t", at);
        at = line.find_first_of(" \t", at);
        if (at == std::string_view::npos) return {};
    }
    std::string rest(line.substr(at));
    rest.erase(0, rest.find_first_not_of(" \t"));
    rest.erase(rest.find_last_not_of(" \t") + 1);
    if (rest.size() >= 2 && rest.front() == '"' && rest.back() == '"')
        rest = rest.substr(1, rest.size() - 2);
    return rest;
}

namespace {

// A --json reply: one line. What a person typed comes back in it (a word that is not a command):
// bytes that are not UTF-8 are replaced, not thrown on (found by fuzz_console).
std::string json_line(const json& reply) {
    return reply.dump(-1, ' ', false, json::error_handler_t::replace) + "\n";
}

const char* kind_name(ConfigKind k) {
    switch (k) {
        case ConfigKind::integer:
            return "integer";
        case ConfigKind::number:
            return "number";
        case ConfigKind::text:
            return "text";
        case ConfigKind::choice:
            return "choice";
        case ConfigKind::flag:
            return "flag";
    }
    return "?";
}

}  // namespace

std::vector<LineAssembler::Line> LineAssembler::feed(std::string_view bytes) {
    std::vector<Line> out;
    for (const char c : bytes) {
        const bool ends = c == '\n' || c == '\r';
        if (c == '\n' && after_cr_) {  // the "\n" of "\r\n"
            after_cr_ = false;
            continue;
        }
        after_cr_ = c == '\r';
        if (ends) {
            out.push_back({std::move(pending_), overflowed_});
            pending_.clear();
            overflowed_ = false;
            continue;
        }
        if (pending_.size() < limit_)
            pending_ += c;
        else
            overflowed_ = true;
    }
    return out;
}

void LogBook::add(const std::string& line) {
    lines_.push_back(line);
    while (lines_.size() > keep_) lines_.pop_front();
}

std::vector<std::string> LogBook::last(std::size_t count) const {
    const std::size_t from = lines_.size() > count ? lines_.size() - count : 0;
    return {lines_.begin() + static_cast<std::ptrdiff_t>(from), lines_.end()};
}

std::string Console::refuse_too_long(const LineAssembler::Line& line) const {
    const bool as_json = line.text.find("--json") != std::string::npos;
    const std::string why = "line longer than " + std::to_string(kConsoleLineLimitBytes) +
                            " bytes refused (nothing was done)";
    if (as_json) return json_line(json{{"ok", false}, {"error", why}});
    return "error: " + why + "\n";
}

// Each command's handler: the line's words (without --json), the line itself, and the reply to
// fill; a refusal is thrown as Refused.
namespace {

using Words = std::vector<std::string>;

}  // namespace

ConfirmedWords words_and_confirm(const std::vector<std::string>& words, std::size_t skip) {
    ConfirmedWords out;
    for (std::size_t i = skip; i < words.size(); ++i)
        if (words[i] != "--json") out.words.push_back(words[i]);
    out.confirmed = !out.words.empty() && out.words.back() == "confirm";
    if (out.confirmed) out.words.pop_back();
    return out;
}

void need_words(const std::vector<std::string>& words, std::size_t n, const std::string& usage) {
    if (words.size() != n) throw ConsoleRefused("usage: " + usage);
}

std::vector<ConsoleCommand> Console::commands() {
    // The order `help` lists them in (docs/appliance.md's Console section follows it).
    std::vector<ConsoleCommand> rows;
    for (auto part : {&Console::status_rows, &Console::config_rows, &Console::cycle_rows,
                      &Console::record_rows, &Console::setup_rows})
        for (auto& row : (this->*part)()) rows.push_back(std::move(row));
    return rows;
}

// help and status.
std::vector<ConsoleCommand> Console::status_rows() {
    return {
        {"help", "help", "this list",
         [this](const Words&, std::string_view, ConsoleReply& r) {
             std::ostringstream out;
             json list = json::array();
             for (const auto& c : table_) {
                 out << "  " << c.usage
                     << std::string(22 - std::min<std::size_t>(21, c.usage.size()), ' ') << c.help
                     << "\n";
                 list.push_back({{"command", c.usage}, {"help", c.help}, {"acts", c.acts}});
             }
             out << "  (--json on any line: the reply as one JSON object)";
             r.text = out.str();
             r.data["commands"] = list;
         }},
        {"status", "status",
         "the state, what the box waits for, the cycle's number and its last error",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "status");
             const Cycle& cycle = c_.cycle;
             const std::string prompt = prompt_text(cycle.prompt());
             r.text = std::string("state: ") + state_name(cycle.state());
             if (!prompt.empty()) r.text += "\nwaiting: " + prompt;
             if (cycle.state() == CycleState::setup_camera)
                 r.text += "\nset-up: view " + std::to_string(cycle.prompt_step() + 1) +
                           ", image covered " +
                           std::to_string(std::lround(100 * cycle.setup_coverage())) + " %";
             r.text += "\ncycle: " + std::to_string(cycle.report().number) + " (" +
                       std::to_string(cycle.cycles_completed()) + " completed since start)";
             if (!cycle.error().empty()) r.text += "\nlast error: " + cycle.error();
             r.data = {{"state", state_name(cycle.state())},
                       {"waiting", prompt},
                       {"cycle", cycle.report().number},
                       {"completed", cycle.cycles_completed()},
                       {"error", cycle.error()},
                       {"setup_coverage", cycle.setup_coverage()}};
         }},
    };
}

// The configuration: list, get, set, save, reset.
void Console::list_config(ConsoleReply& r) const {
    std::ostringstream out;
    json keys = json::object();
    for (const auto& e : c_.config.entries()) {
        const KeyInfo& k = e.info;
        const std::string value = c_.config.get(e.name);
        out << e.name << " = " << (k.kind == ConfigKind::text ? "\"" + value + "\"" : value);
        if (!k.unit.empty()) out << " " << k.unit;
        const std::string fallback = c_.config.default_value(e.name);
        if (value != fallback) out << "  (default " << fallback << ")";
        if (k.needs_restart) out << "  [at start]";
        out << "\n";
        keys[e.name] = {{"value", value},
                        {"default", fallback},
                        {"unit", std::string(k.unit)},
                        {"kind", kind_name(k.kind)},
                        {"min", k.min},
                        {"max", k.max},
                        {"choices", std::string(k.choices)},
                        {"at_start", k.needs_restart},
                        {"doc", std::string(k.doc)}};
    }
    r.text = out.str();
    r.text.pop_back();
    r.data["config"] = keys;
}

std::vector<ConsoleCommand> Console::config_rows() {
    return {
        {"config list", "config list", "every key with its value, unit, range and default",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 2, "config list");
             list_config(r);
         }},
        {"config get", "config get KEY", "one key's value",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 3, "config get KEY");
             const std::string value = c_.config.get(words[2]);
             r.text = words[2] + " = " + value;
             r.data = {{"key", words[2]}, {"value", value}};
         }},
        {"config set", "config set KEY VALUE",
         "change a key (validated; in force from the next cycle)",
         [this](const Words& words, std::string_view line, ConsoleReply& r) {
             if (words.size() < 3) throw Refused("usage: config set KEY VALUE");
             const std::string value = console_words_after(line, 3);
             try {
                 c_.config.set(words[2], value);
             } catch (const ConfigError& e) {
                 throw Refused(e.what());
             }
             if (c_.config_changed) c_.config_changed();
             const bool at_start = c_.config.find(words[2])->info.needs_restart;
             r.text = words[2] + " = " + c_.config.get(words[2]) +
                      (at_start ? " (in force at the next start; config save keeps it)"
                                : " (in force from the next cycle; config save keeps it)");
             r.data = {
                 {"key", words[2]}, {"value", c_.config.get(words[2])}, {"at_start", at_start}};
         }},
        {"config save", "config save",
         "write the configuration (a power cut leaves the old file or the new)",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 2, "config save");
             try {
                 c_.settings.replace_file(c_.settings_name, c_.config.to_toml());
             } catch (const std::runtime_error& e) {
                 throw Refused(std::string("not saved (the saved file is as it was): ") + e.what());
             }
             r.text = "saved " + c_.settings_name;
             r.data = {{"saved", c_.settings_name}};
         },
         /*acts=*/true},
        {"config reset", "config reset [KEY]",
         "one key, or all, back to its default (save to keep it)",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             if (words.size() == 3) {
                 try {
                     c_.config.reset(words[2]);
                 } catch (const ConfigError& e) {
                     throw Refused(e.what());
                 }
                 r.text = words[2] + " = " + c_.config.get(words[2]) + " (the default)";
             } else {
                 need_words(words, 2, "config reset [KEY]");
                 c_.config.reset_all();
                 r.text = "every key back to its default (config save keeps it)";
             }
             if (c_.config_changed) c_.config_changed();
         },
         /*acts=*/true},
    };
}

// The cycle's verbs: start, confirm, cancel, revert.
std::vector<ConsoleCommand> Console::cycle_rows() {
    return {
        {"start", "start", "start a calibration cycle (the button's short press in idle)",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "start");
             Cycle& cycle = c_.cycle;
             if (cycle.state() != CycleState::idle)
                 throw Refused(std::string("busy: ") + state_name(cycle.state()));
             cycle.start();
             r.text = std::string("started: ") + state_name(cycle.state());
         },
         /*acts=*/true},
        {"confirm", "confirm",
         "go on where the box waits: apply in review, the next step in set-up",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "confirm");
             r.text = press_for_prompt(false);
         },
         /*acts=*/true},
        {"cancel", "cancel",
         "stop the cycle (the button's long press); nothing more goes to the machine",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "cancel");
             Cycle& cycle = c_.cycle;
             if (cycle.state() == CycleState::idle) throw Refused("nothing to cancel: idle");
             cycle.cancel("cancelled from the console");
             r.text = std::string("cancelled: ") + state_name(cycle.state());
         },
         /*acts=*/true},
        {"revert", "revert", "send the settings in force before the last completed cycle",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "revert");
             const std::string refused = c_.cycle.revert();
             if (!refused.empty()) throw Refused(refused);
             r.text = "reverting to the settings before cycle " +
                      std::to_string(c_.cycle.report().number);
         },
         /*acts=*/true},
    };
}

// What the box keeps: the last cycle, the log, its version.
std::vector<ConsoleCommand> Console::record_rows() {
    return {
        {"last", "last", "the last completed cycle's result",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "last");
             describe_last(r);
         }},
        {"log", "log [N]", "the last N lines of the box's log (default 20)",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             std::size_t count = 20;
             if (words.size() == 2) {
                 try {
                     count = std::stoul(words[1]);
                 } catch (const std::exception&) {
                     throw Refused("usage: log [N]");
                 }
             } else {
                 need_words(words, 1, "log [N]");
             }
             const auto lines = c_.log.last(count);
             for (const auto& l : lines) r.text += l + "\n";
             if (!r.text.empty()) r.text.pop_back();
             r.data["log"] = lines;
         }},
        {"version", "version", "the firmware's version",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "version");
             r.text = "calbox " + c_.version;
             r.data["version"] = c_.version;
         }},
    };
}

// The set-up on its own, and the button's other presses.
std::vector<ConsoleCommand> Console::setup_rows() {
    return {
        {"camera calibrate", "camera calibrate",
         "set-up: calibrate the camera from board views, then take the plane",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 2, "camera calibrate|plane");
             start_setup(c_.cycle.calibrate_camera(), r);
         },
         /*acts=*/true},
        {"camera plane", "camera plane",
         "set-up: take the bed plane from the board laid on the bed",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 2, "camera calibrate|plane");
             start_setup(c_.cycle.take_plane(), r);
         },
         /*acts=*/true},
        {"capture", "capture", "take the set-up view the box asks for (the button's press)",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "capture");
             r.text = press_for_prompt(true);
         },
         /*acts=*/true},
        {"acknowledge", "acknowledge", "back to idle after an error (the button's press there)",
         [this](const Words& words, std::string_view, ConsoleReply& r) {
             need_words(words, 1, "acknowledge");
             Cycle& cycle = c_.cycle;
             if (cycle.prompt() != Prompt::acknowledge_error)
                 throw Refused(std::string("no error to acknowledge: ") +
                               state_name(cycle.state()));
             cycle.acknowledge();
             r.text = std::string("acknowledged: ") + state_name(cycle.state());
         },
         /*acts=*/true},
    };
}

Console::Console(ConsoleContext context) : c_(std::move(context)), table_(commands()) {
    for (auto& c : c_.more_rows) table_.push_back(std::move(c));
    c_.more_rows.clear();
}

std::string Console::press_for_prompt(bool setup_view_only) {
    Cycle& cycle = c_.cycle;
    const Prompt p = cycle.prompt();
    const bool setup_prompt = p == Prompt::hold_calibration_board || p == Prompt::lay_plane_board;
    if (p == Prompt::none || p == Prompt::start)
        throw Refused(std::string("the box is not waiting for a person (") +
                      state_name(cycle.state()) + ")");
    if (setup_view_only && !setup_prompt)
        throw Refused(std::string("no set-up view is asked for (waiting: ") + prompt_text(p) + ")");
    const std::string was = prompt_text(p);
    cycle.press(false);
    return "done: " + was;
}

void Console::start_setup(const std::string& refused, ConsoleReply& r) {
    if (!refused.empty()) throw Refused(refused);
    r.text = std::string("set-up started: ") + prompt_text(c_.cycle.prompt()) +
             " (capture, confirm or the button)";
}

void Console::describe_last(ConsoleReply& r) {
    const Cycle& cycle = c_.cycle;
    const auto& report = cycle.report();
    if (cycle.cycles_completed() == 0) {
        const auto last = c_.data.read_file("last-cycle");
        if (!last) throw Refused("no cycle has completed yet");
        r.text = "cycle " + last->substr(0, last->find('\n')) +
                 " completed before the box started; its record is in the data directory";
        r.data = {{"cycle", std::atoi(last->c_str())}};
        return;
    }
    r.text = "cycle " + std::to_string(report.number) + ": " +
             (report.applied ? "applied" : "not applied");
    const auto figures = [](const modes::ErrorFigures& f) {
        json j{{"rms_mm", f.rms_mm}, {"max_mm", f.max_mm}};
        if (f.mean_mm) j["mean_mm"] = *f.mean_mm;
        return j;
    };
    const auto line = [](const modes::ErrorFigures& f) {
        return (f.mean_mm ? number_text("%.4f", *f.mean_mm) + " mm mean, " : std::string()) +
               number_text("%.4f", f.rms_mm) + " mm RMS, " + number_text("%.4f", f.max_mm) +
               " mm worst (measured)";
    };
    if (report.measured) r.text += "\nbefore: " + line(*report.measured);
    if (report.verified) r.text += "\nafter: " + line(*report.verified);
    const auto goal = cycle.mode().goal();
    const bool met = cycle.goal_met();
    if (report.verified) r.text += "\ngoal (" + goal.describe() + "): " + (met ? "met" : "not met");
    r.data = {{"cycle", report.number},
              {"applied", report.applied},
              {"mode", goal.mode},
              {"goal", goal.describe()},
              {"goal_met", met}};
    cycle.mode().describe_last(r.text, r.data);
    if (report.measured) r.data["before"] = figures(*report.measured);
    if (report.verified) r.data["after"] = figures(*report.verified);
}

std::string Console::reply_to(std::string_view line) {
    std::vector<std::string> words = words_of(line);
    bool as_json = false;
    std::erase_if(words, [&](const std::string& w) {
        if (w != "--json") return false;
        as_json = true;
        return true;
    });
    if (const auto why = control_byte_refusal(line)) {
        if (as_json) return json_line(json{{"ok", false}, {"error", *why}});
        return "error: " + *why + "\n";
    }
    std::string clean(line);
    if (const auto at = clean.find("--json"); at != std::string::npos) clean.erase(at, 6);
    // An empty line is not answered; "--json" alone asks for an answer (found by fuzz_console).
    if (words.empty())
        return as_json ? json_line(json{{"ok", false}, {"error", "no command (help lists them)"}})
                       : std::string();

    ConsoleReply r;
    try {
        row_for(table_, words).run(words, clean, r);
    } catch (const std::exception& e) {
        // Whatever a row throws (a refusal, a key the configuration does not have, a file that
        // cannot be written) is this line's answer: nothing typed ends the box.
        if (as_json) return json_line(json{{"ok", false}, {"error", e.what()}});
        return std::string("error: ") + e.what() + "\n";
    }
    if (as_json) {
        json out = r.data;
        out["ok"] = true;
        return json_line(out);
    }
    return r.text + "\n";
}

ConsoleLink::ConsoleLink(EventLoop& loop, std::unique_ptr<hal::SerialPort> port, Console& console,
                         Log log, Reopen reopen, hal::Clock* clock)
    : loop_(loop),
      port_(std::move(port)),
      console_(console),
      log_(std::move(log)),
      reopen_(std::move(reopen)) {
    if (reopen_) {
        if (clock == nullptr) throw std::logic_error("a console that reopens needs a clock");
        retry_ = clock->make_timer();
        loop_.watch(retry_->fd(), [this] {
            retry_->take_expirations();
            try_reopen();
        });
    }
    if (port_) {
        loop_.watch(port_->fd(), [this] { on_readable(); });
        watching_ = true;
    } else if (reopen_) {
        retry_->arm(std::chrono::seconds(1), std::chrono::seconds(1));
    }
}

ConsoleLink::~ConsoleLink() {
    if (watching_) loop_.unwatch(port_->fd());
    if (retry_) loop_.unwatch(retry_->fd());
}

void ConsoleLink::lost(const std::string& why) {
    if (watching_) loop_.unwatch(port_->fd());
    watching_ = false;
    port_.reset();
    lines_ = LineAssembler(kConsoleLineLimitBytes);  // half a line from before is not a command
    if (!reopen_) {
        log_.warning("console: " + why + " (the console is off; the box goes on)");
        return;
    }
    log_.warning("console: " + why + " (opened again when it is back; the box goes on)");
    retry_->arm(std::chrono::seconds(1), std::chrono::seconds(1));
}

void ConsoleLink::try_reopen() {
    try {
        port_ = reopen_();
    } catch (const std::runtime_error&) {
        return;  // still not there: said once, when it went
    }
    retry_->disarm();
    loop_.watch(port_->fd(), [this] { on_readable(); });
    watching_ = true;
    log_("console: back");
}

void ConsoleLink::notice(const std::string& line) {
    send("notice: " + line + "\n");
}

void ConsoleLink::on_readable() {
    std::uint8_t buffer[512];
    std::size_t n = 0;
    try {
        n = port_->read_some(buffer);
    } catch (const std::runtime_error& e) {
        lost(e.what());
        return;
    }
    for (const auto& line : lines_.feed({reinterpret_cast<const char*>(buffer), n})) {
        send(line.too_long ? console_.refuse_too_long(line) : console_.reply_to(line.text));
    }
}

void ConsoleLink::send(const std::string& text) {
    if (!port_) return;  // gone: what it would have said is in the log
    // Nobody may be reading (a pty with no client): what does not fit is dropped, said once.
    std::size_t sent = 0;
    try {
        while (sent < text.size()) {
            const std::size_t n = port_->write_some(
                {reinterpret_cast<const std::uint8_t*>(text.data()) + sent, text.size() - sent});
            if (n == 0) break;
            sent += n;
        }
    } catch (const std::runtime_error& e) {
        lost(e.what());
        return;
    }
    if (sent < text.size() && !dropped_told_) {
        dropped_told_ = true;
        log_.warning("console: nobody reads the console; replies are dropped until someone does");
    } else if (sent == text.size()) {
        dropped_told_ = false;
    }
}

}  // namespace calbox::firmware
