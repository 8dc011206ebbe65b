#pragma once
// Streams G-code to Marlin or RepRapFirmware the way their hosts do (OctoPrint, Pronterface):
// every line numbered and checksummed after an M110, a window of lines in flight (one by
// default) each released by an `ok`, `Resend: N` / `rs N` answered from line N, `busy:` keeping
// the link alive, `Error:` lines that are not about the line's transport ending the job, a
// start-up banner mid-job (the printer reset) abandoning it, never resuming it blindly.
#include <chrono>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "firmware/links/machine_link.hpp"
#include "hal/clock.hpp"
#include "hal/log.hpp"
#include "hal/serial_port.hpp"

namespace calbox::firmware {

struct GcodeHostSettings {
    int window = 1;  // lines sent before the first is acknowledged
    // Silence after a line before the printer is declared gone; `busy:` restarts it.
    std::chrono::milliseconds reply_timeout{30000};
    int max_resends_of_a_line = 8;  // beyond this the link is too noisy to trust
    // A board that resets when its port opens (Marlin on an Arduino) loses what is sent while it
    // boots: the first job waits this long for its start-up banner unless the printer has
    // spoken already; zero does not wait.
    std::chrono::milliseconds startup_wait{3000};
    std::size_t transcript_lines = 200000;  // about two whole delta cycles with resends
    // Marlin and RepRapFirmware: each line numbered and checksummed, a job opened by M110 N0, a
    // line the printer read wrong sent again when it asks. grbl reads neither (a `*` is its
    // error:1, M110 its error:20): plain lines, each answered by ok or error:N.
    bool numbered_lines = true;
};

// The machine link over a serial port the box owns.
class GcodeHost final : public MachineLink {
  public:
    using Log = hal::Log;
    GcodeHost(hal::SerialPort& port, hal::Clock& clock, GcodeHostSettings settings, Log log);

    int port_fd() const { return port_.fd(); }
    int timer_fd() const { return timer_->fd(); }
    // Streams `lines` (comments and blank lines dropped); `done` is called once, on the caller's
    // thread, from on_readable() or on_timer(). Throws std::logic_error while a job runs.
    void start_job(const std::vector<std::string>& lines, std::function<void(JobOutcome)> done);
    bool busy() const override { return static_cast<bool>(done_); }
    void on_readable();
    void on_timer();
    // Ends the running job with `why`; nothing more is sent.
    void cancel(const std::string& why) override;

    // As a machine link: a job and a command are both streamed.
    void attach(EventLoop& loop) override;
    void detach(EventLoop& loop) override;
    std::string describe() const override { return "serial"; }
    void run_job(const std::vector<std::string>& lines, Done done) override {
        start_job(lines, std::move(done));
    }
    void send_commands(const std::vector<std::string>& lines, Done done) override {
        start_job(lines, std::move(done));
    }
    std::string closing_note() const override { return "the machine link is closed"; }
    // Not empty once the device vanished: what was seen. Stop watching port_fd() then.
    const std::string& link_gone() const { return gone_; }
    // Whether anything has come from the printer since the port opened (its banner, an ok).
    bool heard_from_printer() const { return heard_from_printer_; }
    // The lines written to the printer, in order, resends included: the last
    // `transcript_lines` of them at most (a box that runs for months keeps a bounded record).
    const std::deque<std::string>& transcript() const { return transcript_; }
    // Every line handed to the port since start-up, resends included.
    std::size_t lines_written() const { return lines_written_; }

  private:
    void handle(const std::string& reply);
    void handle_resend(const std::string& reply);  // Marlin's Resend:, RepRapFirmware's rs
    void handle_action(const std::string& reply);  // a host action: //action:cancel, pause, ...
    void pump();
    void write_line(const std::string& text);
    void flush();
    void finish(bool ok, const std::string& error);
    void arm_deadline();
    std::string last_sent() const;  // "line N: TEXT", the last line written

    hal::SerialPort& port_;
    std::unique_ptr<hal::Timer> timer_;
    GcodeHostSettings settings_;
    Log log_;
    std::vector<std::string> job_;  // job_[n] is line number n (0: the M110)
    std::size_t next_ = 0;          // the next line number to send
    std::size_t lines_written_ = 0;
    int in_flight_ = 0;  // lines sent, not yet acknowledged
    bool heard_from_printer_ = false;
    bool waiting_for_startup_ = false;
    int resends_of_line_ = 0;
    std::size_t last_resend_ = 0;
    bool paused_ = false;
    std::string incoming_, outgoing_;
    std::vector<std::string> replies_;
    std::deque<std::string> transcript_;
    std::function<void(JobOutcome)> done_;
    std::string gone_;
};

}  // namespace calbox::firmware
