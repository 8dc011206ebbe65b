#pragma once
// What the sim board's twin hosts share (Moonraker, OctoPrint, Duet stand in front of the same
// twin bench): their faults, their disk (files replaced whole), a multipart upload's fields, and
// the print a host runs on its own once a job is uploaded and started.
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "drivers/http_server.hpp"

namespace calbox::sim {

class TwinBench;

// [faults] keys for a printer behind a host (zero and false: off).
struct HostFaults {
    bool wrong_key = false;          // the host takes another key than the box's file holds
    bool printer_not_ready = false;  // the firmware behind the host is not ready (Klipper's
                                     // start-up error, OctoPrint's printer not connected)
    bool print_cancelled = false;    // someone cancels the box's first print on the host
    bool upload_refused = false;     // the host refuses to store a file (its disk full)
    // The host takes the box's job and says it will print it, but never starts (a printer that
    // dropped off its host as the job arrived).
    bool print_never_starts = false;
    int restart_at_request = 0;  // the host restarts at its n-th request
    // A Duet restarts on the first G-code line that starts so, before running it (a batch of
    // settings cut off part way: "M666").
    std::string restart_at_command;
    int silent_at_request = 0;         // from its n-th request on, it never replies
    bool config_edited = false;        // someone edits printer.cfg after the box first reads it
    bool new_config_rejected = false;  // Klipper refuses the printer.cfg the box writes
    bool any() const {
        return wrong_key || printer_not_ready || print_cancelled || upload_refused ||
               print_never_starts || restart_at_request > 0 || silent_at_request > 0 ||
               config_edited || new_config_rejected || !restart_at_command.empty();
    }
};

struct TwinHostSettings {
    std::string api_key;  // the key, or the password for a Duet
    HostFaults faults;
    double print_radius_mm = 85;  // printer.cfg's, when a Klipper host writes it first
    double print_seconds = 0;     // a print lasts at least this long
    bool duet_sbc = false;        // a Duet with an SBC: DuetSoftwareFramework's /machine API
};

// A twin host serving on loopback (each kind its own API in front of the same bench).
class TwinHostServer {
  public:
    virtual ~TwinHostServer() = default;
    virtual std::string url() const = 0;  // "http://127.0.0.1:PORT"
};

// A file replaced whole: written beside and renamed over. Throws std::runtime_error.
void write_file_whole(const std::filesystem::path& path, const std::string& text);
std::string read_whole_file(const std::filesystem::path& path);  // throws std::runtime_error

// A multipart/form-data body's fields: name -> (file name, contents).
std::map<std::string, std::pair<std::string, std::string>> form_fields(
    const std::string& content_type, const std::string& body);

// The print a host runs on the bench, line by line on a thread of its own: at least
// `seconds` long, cancelled half-way when told (the host_print_cancelled fault).
class TwinPrint {
  public:
    enum class State { idle, printing, complete, cancelled, error };
    explicit TwinPrint(std::shared_ptr<TwinBench> bench) : bench_(std::move(bench)) {}
    TwinPrint(const TwinPrint&) = delete;
    TwinPrint& operator=(const TwinPrint&) = delete;
    ~TwinPrint() { stop(); }
    // Throws std::logic_error while one runs.
    void start(const std::string& name, const std::string& job, double seconds,
               bool cancel_half_way);
    void stop();  // a host restarting: the print is gone, the state idle
    State state() const;
    std::string message() const;  // why it ended in error
    std::string name() const;
    double completion() const;  // 0 .. 1
    int started() const { return started_; }

  private:
    std::shared_ptr<TwinBench> bench_;
    mutable std::mutex mutex_;
    State state_ = State::idle;
    std::string name_, message_;
    double completion_ = 0;
    int started_ = 0;
    std::atomic<bool> stop_{false};
    std::thread thread_;
};

// What every twin host holds: the bench it stands in front of, its disk, its key, its faults,
// the print it runs, its request count and its server. Each twin's own state derives from it and
// starts the server last (its handlers use the rest).
struct TwinHostCore {
    std::shared_ptr<TwinBench> bench;
    std::filesystem::path dir;
    std::string key;
    HostFaults faults;
    double print_seconds = 0;
    double print_radius_mm = 85;
    bool duet_sbc = false;
    std::unique_ptr<TwinPrint> print;
    std::atomic<int> requests{0};
    std::atomic<bool> stopping{false};
    std::unique_ptr<drivers::HttpServer> server;
    std::atomic<std::chrono::steady_clock::rep> restarting_until{0};

    TwinHostCore(std::shared_ptr<TwinBench> bench, std::filesystem::path dir,
                 TwinHostSettings settings);
    TwinHostCore(const TwinHostCore&) = delete;
    TwinHostCore& operator=(const TwinHostCore&) = delete;
    virtual ~TwinHostCore() = default;
    // Counts a request: its number, from 1.
    int count_request() { return ++requests; }
    // Under host_silent_at_request, the n-th request and those after it get no answer until the
    // host stops (the client's own timeout ends its wait): true when it was held so.
    bool held_silent(int n) const;
    // Under host_restart_at_request: whether the n-th request restarts the host. If it does, the
    // print stops, every connection drops, and for 1.5 s the host is starting (restarting()).
    bool restarts_at(int n);
    void restart_now();  // the same, now
    bool restarting() const;
    std::string url() const;  // "http://127.0.0.1:PORT"
    // Stops serving (every handler done) and the print, before the twin's own state goes.
    void shut_down();
};

}  // namespace calbox::sim
