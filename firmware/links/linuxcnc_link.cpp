#include "firmware/links/linuxcnc_link.hpp"

#include <algorithm>
#include <cctype>
#include <memory>
#include <set>

namespace calbox::firmware {
namespace {

std::string upper(std::string text) {
    for (auto& c : text) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return text;
}

std::string first_word(const std::string& text) {
    const auto end = text.find(' ');
    return end == std::string::npos ? text : text.substr(0, end);
}

// Whether the line ends a program (M2, M30), outside its comments.
bool ends_program(const std::string& line) {
    std::string words;
    int depth = 0;
    for (const char c : line) {
        if (c == ';' && depth == 0) break;
        if (c == '(') ++depth;
        if (depth == 0 && c != ' ' && c != '\t') words += static_cast<char>(std::toupper(c));
        if (c == ')' && depth > 0) --depth;
    }
    for (std::size_t at = words.find('M'); at != std::string::npos; at = words.find('M', at + 1)) {
        std::size_t end = at + 1;
        while (end < words.size() && std::isdigit(static_cast<unsigned char>(words[end]))) ++end;
        if (end == at + 1 || (end < words.size() && words[end] == '.')) continue;
        const int number = std::stoi(words.substr(at + 1, end - at - 1));
        if (number == 2 || number == 30) return true;
    }
    return false;
}

bool blank(const std::string& line) {
    return std::all_of(line.begin(), line.end(),
                       [](unsigned char c) { return std::isspace(c) != 0; });
}

}  // namespace

// One connection's conversation, on the request thread.
class LinuxCncLink::Talk {
  public:
    Talk(LinuxCncLink& link, std::unique_ptr<hal::TextConnection> connection)
        : link_(link), settings_(link.settings_), connection_(std::move(connection)) {}
    Talk(const Talk&) = delete;
    Talk& operator=(const Talk&) = delete;
    ~Talk() {
        try {
            connection_->write_line("quit");
        } catch (const std::exception&) {  // NOLINT(bugprone-empty-catch): the peer is gone
        }
    }

    void hello() {
        send("hello " + settings_.connect_password + " calbox 1.0");
        const std::string reply = next_reply(settings_.connect_timeout, "hello");
        if (upper(reply).starts_with("HELLO ACK")) return;
        if (upper(reply).starts_with("HELLO NAK"))
            throw LinkError(where() +
                            " refused the connect password (linuxcncrsh's --connectpw: the key "
                            "file's first word)");
        throw LinkError(where() + " answered hello with '" + reply + "': not linuxcncrsh");
    }

    // The settings a request needs, in order: each refused one ends it, saying which.
    void take_control() {
        // Echo is on until told off: what the box sends comes back, and is skipped as such.
        send("set echo off");
        set("verbose on", "VERBOSE");
        if (!try_set("enable " + settings_.enable_password, "ENABLE"))
            throw LinkError(where() +
                            " refused the enable password (linuxcncrsh's --enablepw: the key "
                            "file's second word)");
        const std::string machine = get("machine", "MACHINE");
        if (upper(machine) != "MACHINE ON")
            throw LinkError(where() + ": the machine is not on (" + machine +
                            "): release the e-stop, turn it on and home it first");
        set("mode mdi", "MODE");
        // LinuxCNC 2.9 names it wait_mode; 2.8 knew only set_wait.
        if (!try_set("wait_mode done", "WAIT_MODE")) set("set_wait done", "SET_WAIT");
        set("linear_unit_conversion mm", "LINEAR_UNIT_CONVERSION");
        // LinuxCNC queues its errors and GET ERROR takes the oldest: those from before this
        // request go first, so that a refusal is named by its own.
        for (const auto& earlier : errors())
            link_.log()("linuxcnc: an earlier error, before calbox's request: " + earlier);
    }

    // One G-code line by MDI, done before this returns.
    void mdi(const std::string& line, std::size_t number) {
        send("set mdi " + line);
        const auto until = std::chrono::steady_clock::now() + settings_.reply_timeout;
        for (;;) {
            if (link_.stop_asked()) {
                abort();
                throw LinkError("stopped");
            }
            const auto reply = read_skipping_echoes(std::chrono::milliseconds(200));
            if (!reply) {
                if (std::chrono::steady_clock::now() < until) continue;
                abort();
                throw LinkError(where() + ": line " + std::to_string(number) + " '" + line +
                                "' not done within " +
                                std::to_string(settings_.reply_timeout.count() / 1000) +
                                " s (aborted)");
            }
            const std::string word = upper(*reply);
            if (word == "SET MDI ACK") return;
            if (word == "SET MDI NAK" || word.starts_with("ERROR")) {
                std::string because;
                for (const auto& e : errors()) because += (because.empty() ? "" : "; ") + e;
                throw LinkError(
                    "LinuxCNC refused line " + std::to_string(number) + " '" + line +
                    "': " + (because.empty() ? "no error text from LinuxCNC" : because));
            }
            if (word == "SET NAK") throw LinkError(where() + " took no SET: not linked");
            link_.log()("linuxcnc: " + *reply);
        }
    }

    // A query of linuxcncrsh's own: its answer line, which starts with `word`.
    std::string get(const std::string& what, const std::string& word) {
        send("get " + what);
        for (;;) {
            std::string reply = next_reply(settings_.reply_timeout, "get " + what);
            const std::string u = upper(reply);
            if (u.starts_with(word)) return reply;
            if (u.starts_with("GET ") && u.ends_with(" NAK")) {
                std::string why = where();
                why += " refused 'get ";
                why += what;
                why += "' (";
                why += reply;
                why += ")";
                throw LinkError(why);
            }
            link_.log()("linuxcnc: " + reply);
        }
    }

  private:
    std::string where() const {
        return "LinuxCNC at " + settings_.host + ":" + std::to_string(settings_.port);
    }

    void send(const std::string& line) {
        sent_.insert(line);
        try {
            connection_->write_line(line);
        } catch (const hal::NetworkError& e) {
            throw LinkError(std::string("LinuxCNC: ") + e.what());
        }
    }

    std::optional<std::string> read_skipping_echoes(std::chrono::milliseconds timeout) {
        try {
            for (;;) {
                auto line = connection_->read_line(timeout);
                if (!line) return line;
                if (blank(*line) || sent_.count(*line) != 0) continue;
                return line;
            }
        } catch (const hal::NetworkError& e) {
            throw LinkError(std::string("LinuxCNC: ") + e.what());
        }
    }

    std::string next_reply(std::chrono::milliseconds timeout, const std::string& to) {
        const auto until = std::chrono::steady_clock::now() + timeout;
        for (;;) {
            link_.check_stop();
            if (auto reply = read_skipping_echoes(std::chrono::milliseconds(200))) return *reply;
            if (std::chrono::steady_clock::now() >= until)
                throw LinkError(where() + ": no answer to '" + first_word(to) + " ...' within " +
                                std::to_string(timeout.count() / 1000) + " s");
        }
    }

    bool try_set(const std::string& what, const std::string& word) {
        send("set " + what);
        for (;;) {
            const std::string reply = next_reply(settings_.reply_timeout, "set " + what);
            const std::string u = upper(reply);
            if (u == "SET " + word + " ACK") return true;
            if (u == "SET " + word + " NAK" || u == "SET NAK") return false;
            if (u.starts_with("ERROR:")) return false;
            link_.log()("linuxcnc: " + reply);  // a warning ("set_wait" is deprecated)
        }
    }

    void set(const std::string& what, const std::string& word) {
        if (!try_set(what, word)) throw LinkError(where() + " refused 'set " + what + "'");
    }

    void abort() {
        try {
            connection_->write_line("set abort");
        } catch (const std::exception&) {  // NOLINT(bugprone-empty-catch): the peer is gone
        }
    }

    // Every error LinuxCNC holds, oldest first, until its "ERROR OK" (a bounded number: a
    // controller that keeps making them is not waited out).
    std::vector<std::string> errors() {
        std::vector<std::string> out;
        for (int i = 0; i < 32; ++i) {
            const std::string reply = get("error", "ERROR");
            std::string text = reply.size() > 6 ? reply.substr(6) : std::string();
            if (text.empty() || upper(text) == "OK") break;
            out.push_back(text);
        }
        return out;
    }

    LinuxCncLink& link_;
    const LinuxCncSettings& settings_;
    std::unique_ptr<hal::TextConnection> connection_;
    std::set<std::string> sent_;
};

LinuxCncLink::LinuxCncLink(LinuxCncSettings settings, hal::Network& network, Log log)
    : HostLink("linuxcnc", settings.host + ":" + std::to_string(settings.port), std::move(log)),
      settings_(std::move(settings)),
      network_(network) {}

LinuxCncLink::~LinuxCncLink() {
    finish_requests();
}

void LinuxCncLink::run_job(const std::vector<std::string>& lines, Done done) {
    start([this, lines] { return converse(lines, false); }, std::move(done));
}

void LinuxCncLink::send_commands(const std::vector<std::string>& lines, Done done) {
    start([this, lines] { return converse(lines, true); }, std::move(done));
}

JobOutcome LinuxCncLink::converse(const std::vector<std::string>& lines, bool queries) {
    // Before anything is sent: a line linuxcncrsh would cut, or one it would read as two.
    for (std::size_t i = 0; i < lines.size(); ++i) {
        if (lines[i].size() > kLinuxCncLongestLine)
            throw LinkError("line " + std::to_string(i + 1) + " is " +
                            std::to_string(lines[i].size()) + " characters: linuxcncrsh takes " +
                            std::to_string(kLinuxCncLongestLine) + " at most");
        if (lines[i].find_first_of("\r\n") != std::string::npos)
            throw LinkError("line " + std::to_string(i + 1) + " holds a line break");
    }
    // MDI runs no program end (LinuxCNC refuses M2 and M30 there): a job's last line that ends
    // it is sent as what it does to the machine, the spindle and coolant off; one elsewhere
    // would cut the job, and is refused.
    std::vector<std::string> sent = lines;
    std::size_t last = sent.size();
    while (last > 0 && blank(sent[last - 1])) --last;
    for (std::size_t i = 0; i < last; ++i) {
        if (!ends_program(sent[i])) continue;
        if (i + 1 != last)
            throw LinkError("line " + std::to_string(i + 1) + " '" + sent[i] +
                            "' ends the program before its last line: LinuxCNC's MDI runs no "
                            "program end");
        log()("linuxcnc: the job's last line '" + sent[i] +
              "' ends a program, which MDI does not run: sent as M5 M9 (spindle and coolant "
              "off)");
        sent[i] = "M5 M9";
    }
    check_stop();
    std::unique_ptr<hal::TextConnection> connection;
    try {
        connection =
            network_.connect_text(settings_.host, settings_.port, settings_.connect_timeout);
    } catch (const hal::NetworkError& e) {
        throw LinkError(std::string("LinuxCNC: ") + e.what() +
                        " (is linuxcncrsh running? LinuxCNC's INI [APPLICATIONS] APP = "
                        "linuxcncrsh)");
    }
    Talk talk(*this, std::move(connection));
    talk.hello();
    talk.take_control();
    JobOutcome outcome{true, {}, {}, {}};
    for (std::size_t i = 0; i < sent.size(); ++i) {
        const std::string& line = sent[i];
        if (blank(line)) continue;
        if (queries && line.starts_with(kLinuxCncQuery)) {
            const std::string what = line.substr(4);
            outcome.replies.push_back(talk.get(what, upper(first_word(what))));
            continue;
        }
        talk.mdi(line, i + 1);
    }
    return outcome;
}

}  // namespace calbox::firmware
