#pragma once
// The box's line console: the same commands over a UART, the sim board's pseudo-terminal or
// standard input. Console turns one line into its reply and knows nothing of the device;
// ConsoleLink reads lines from a device on the event loop and writes the replies and the box's
// notices back.
#include <cstddef>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "firmware/cycle/cycle.hpp"
#include "firmware/loop/event_loop.hpp"
#include "firmware/settings/settings_table.hpp"
#include "hal/clock.hpp"
#include "hal/log.hpp"
#include "hal/serial_port.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

// Where the console is read: a serial device's path, "pty", "stdin" or "" for none.
struct ConsoleSettings {
    std::string device = "stdin";
    int baud = 115200;
};

// The console's table of the configuration: [console].
SettingsTable<ConsoleSettings> console_settings_table();

// A line longer than this is refused whole, never cut: a cut line could be a different
// command (`config set records.keep_cycles 1000` cut to `... 1`).
constexpr std::size_t kConsoleLineLimitBytes = 256;

// Bytes to lines; "\n", "\r" or "\r\n" end one (terminal programs send "\r" for Enter).
class LineAssembler {
  public:
    explicit LineAssembler(std::size_t limit_bytes) : limit_(limit_bytes) {}
    struct Line {
        std::string text;
        bool too_long = false;  // the text is its first limit bytes
    };
    std::vector<Line> feed(std::string_view bytes);

  private:
    std::size_t limit_;
    std::string pending_;
    bool overflowed_ = false;
    bool after_cr_ = false;
};

// The box's recent log lines, for the console's `log`.
class LogBook {
  public:
    explicit LogBook(std::size_t keep = 200) : keep_(keep) {}
    void add(const std::string& line);
    std::vector<std::string> last(std::size_t count) const;

  private:
    std::size_t keep_;
    std::deque<std::string> lines_;
};

// A command's reply: the human form (without the final newline) and the --json one.
struct ConsoleReply {
    std::string text;
    nlohmann::json data = nlohmann::json::object();
};

// A command refused: one line, and nothing was done.
class ConsoleRefused : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// One row of the console's table: the words that name it ("config set"), its usage and help
// line, and what it does (throwing ConsoleRefused to refuse).
struct ConsoleCommand {
    std::string name;
    std::string usage;
    std::string help;
    std::function<void(const std::vector<std::string>& words, std::string_view line,
                       ConsoleReply& reply)>
        run;
    // Said as it is (its name alone), the row acts: it starts, stops or steers the cycle, moves
    // the machine, or writes the configuration. `help --json` says so, so that a test sending
    // every row bare leaves these out without a list of its own.
    bool acts = false;
};

// What follows a line's first `skip` words, trimmed; a value in double quotes loses them (a
// row's free text: `config set KEY VALUE`, `web password PASSWORD`).
std::string console_words_after(std::string_view line, std::size_t skip);
// A row's own words after its first `skip` (its name), without --json, and whether the last of
// them is `confirm` (taken off): a row that moves the machine or sets the controller acts only
// with it, and says without it what it would do.
struct ConfirmedWords {
    std::vector<std::string> words;
    bool confirmed = false;
};
ConfirmedWords words_and_confirm(const std::vector<std::string>& words, std::size_t skip);
// A row that takes exactly `n` words (its own included): anything else is refused with its
// usage, so that "quit now" or "start later" does nothing.
void need_words(const std::vector<std::string>& words, std::size_t n, const std::string& usage);

struct ConsoleContext {
    Cycle& cycle;
    Configuration& config;   // the configuration in force
    hal::Storage& settings;  // where `config save` writes
    std::string settings_name;
    hal::Storage& data;  // the cycles' records, for `last`
    const LogBook& log;
    std::string version;
    // Called after the configuration changed (set or reset), to put it in force.
    std::function<void()> config_changed;
    // Other parts' own rows (the job desk's, OctoPrint's key, the web page's password, the sim
    // board's press, hold and quit), listed after the console's own, in this order.
    std::vector<ConsoleCommand> more_rows;
};

class Console {
  public:
    explicit Console(ConsoleContext context);
    // The reply to one line, newline-terminated; "" for an empty line. With --json anywhere on
    // the line the reply is one JSON object: {"ok":true,...} or {"ok":false,"error":"..."}.
    std::string reply_to(std::string_view line);
    std::string refuse_too_long(const LineAssembler::Line& line) const;
    // Its table, its own rows and then the other parts', as `help` lists them.
    const std::vector<ConsoleCommand>& rows() const { return table_; }
    // A part's own rows, added as it starts (the network's `web tls`): listed after the others.
    void add_rows(std::vector<ConsoleCommand> rows) {
        for (auto& row : rows) table_.push_back(std::move(row));
    }

  private:
    std::vector<ConsoleCommand> commands();
    std::vector<ConsoleCommand> status_rows();
    std::vector<ConsoleCommand> config_rows();
    // `config list`: every key with its value, unit, range and default.
    void list_config(ConsoleReply& r) const;
    std::vector<ConsoleCommand> cycle_rows();
    std::vector<ConsoleCommand> record_rows();
    std::vector<ConsoleCommand> setup_rows();
    std::string press_for_prompt(bool setup_view_only);
    void start_setup(const std::string& refused, ConsoleReply& reply);
    void describe_last(ConsoleReply& reply);
    ConsoleContext c_;
    std::vector<ConsoleCommand> table_;
};

class ConsoleLink {
  public:
    using Log = hal::Log;
    // Opens the console's device again: a UART whose USB adapter was unplugged comes back under
    // the same (by-id) path. Throws std::runtime_error while it is not there.
    using Reopen = std::function<std::unique_ptr<hal::SerialPort>()>;
    // Watches the port on the loop until it is gone (standard input closed, a UART unplugged).
    // With `reopen` (and `clock` for its timer) a port that is gone, or null at the start (the
    // device not there when the box started), is tried again every second.
    ConsoleLink(EventLoop& loop, std::unique_ptr<hal::SerialPort> port, Console& console, Log log,
                Reopen reopen = {}, hal::Clock* clock = nullptr);
    ConsoleLink(const ConsoleLink&) = delete;
    ConsoleLink& operator=(const ConsoleLink&) = delete;
    ~ConsoleLink();
    // An unsolicited line (a set-up view's result, a prompt): "notice: ..." on the console.
    void notice(const std::string& line);

  private:
    void on_readable();
    void send(const std::string& text);
    void lost(const std::string& why);
    void try_reopen();
    EventLoop& loop_;
    std::unique_ptr<hal::SerialPort> port_;
    Console& console_;
    Log log_;
    Reopen reopen_;
    std::unique_ptr<hal::Timer> retry_;
    LineAssembler lines_{kConsoleLineLimitBytes};
    bool watching_ = false;
    bool dropped_told_ = false;
};

}  // namespace calbox::firmware
