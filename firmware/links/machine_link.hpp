#pragma once
// What the cycle asks of the machine beside the box, whatever carries it: a serial port the box
// owns (firmware/links/gcode_host.hpp streams G-code over it) or a host that owns the printer's
// port (Klipper's Moonraker: firmware/links/moonraker_link.hpp). The cycle and the modes see only
// this.
#include <functional>
#include <string>
#include <vector>

namespace calbox::firmware {

class EventLoop;

struct JobOutcome {
    bool ok = false;
    std::string error;                 // one line, when not ok
    std::vector<std::string> replies;  // what the printer said besides ok / resend (reports)
    std::string text;                  // a file read from the host, whole
};

class MachineLink {
  public:
    using Done = std::function<void(JobOutcome)>;
    virtual ~MachineLink() = default;

    // Its descriptors watched on the loop, whose thread then calls every `done`.
    virtual void attach(EventLoop& loop) = 0;
    virtual void detach(EventLoop& loop) = 0;
    // "serial", "moonraker http://printer.local:7125": for the log.
    virtual std::string describe() const = 0;

    // A job the machine runs to its end: streamed line by line, or uploaded to the host and
    // started there. `done` once. Throws std::logic_error while another request runs.
    virtual void run_job(const std::vector<std::string>& lines, Done done) = 0;
    // Commands whose replies the caller reads (a settings report, a probe): `done` with what the
    // printer said.
    virtual void send_commands(const std::vector<std::string>& lines, Done done) = 0;
    virtual bool busy() const = 0;
    // Ends the request in flight with `why`: nothing more is sent for it.
    virtual void cancel(const std::string& why) = 0;
    // For the log when the box stops: what becomes of the link and of a job in flight.
    virtual std::string closing_note() const = 0;

    // A firmware that keeps its settings in a configuration file on its host (Klipper's
    // printer.cfg) is configured through that file. False for a link without one; the three
    // calls below then end in an error.
    virtual bool has_config_file() const { return false; }
    // The file as it is on the host now (`done`'s text).
    virtual void read_config_file(Done done) { done(not_a_host()); }
    // Replaces the file with `text` only while it still reads `expected_now` (someone may have
    // changed it since it was read), restarts the firmware to take it and waits until it is
    // ready again. The file on the host is the old one or the new one, never a mix.
    virtual void replace_config_file(const std::string& text, const std::string& expected_now,
                                     Done done) {
        (void)text;
        (void)expected_now;
        done(not_a_host());
    }
    // Settings the firmware itself writes into that file: `lines` change them (Klipper's SET_SKEW
    // and SKEW_PROFILE SAVE), then the firmware saves them (SAVE_CONFIG) and restarts to take
    // them; `done` once it is ready again.
    virtual void save_config_after(const std::vector<std::string>& lines, Done done) {
        (void)lines;
        done(not_a_host());
    }
    // The settings in force as the firmware read them (Klipper's configfile.settings), written
    // as a configuration file's sections (`done`'s text).
    virtual void read_settings_in_force(Done done) { done(not_a_host()); }

  private:
    static JobOutcome not_a_host() {
        return {false, "the machine link has no configuration file on a host", {}, {}};
    }
};

}  // namespace calbox::firmware
