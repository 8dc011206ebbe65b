#pragma once
// What every link to a printer's host shares (Moonraker, OctoPrint, Duet, LinuxCNC's
// linuxcncrsh): each request runs on
// a thread of its own, blocking on the host's API; its `done` comes back through the event loop.
// A cancel or the box stopping ends the request at its next wait; a print running on the host is
// left to the host, and said so.
#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "firmware/links/machine_link.hpp"
#include "hal/background_job.hpp"
#include "hal/http.hpp"
#include "hal/log.hpp"

namespace calbox::firmware {

// What ends a request to a host: its text is the outcome's one line.
class LinkError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// A host's refusal as one line: "HTTP 400: Insufficient disk space", the message from the reply's
// JSON as OctoPrint ({"error": "..."}) or Moonraker ({"error": {"message": "..."}}) gives it, or
// the status alone.
std::string http_error_line(const hal::HttpResponse& reply);

class HostLink : public MachineLink {
  public:
    using Log = hal::Log;
    // `name`: "moonraker", "octoprint", "duet", for the log.
    HostLink(std::string name, net::Url url, hal::HttpClient& http, Log log);
    // A host spoken to in its own protocol (not HTTP) at `address` ("HOST:PORT").
    HostLink(std::string name, std::string address, Log log);

    void attach(EventLoop& loop) final;
    void detach(EventLoop& loop) final;
    std::string describe() const final { return name_ + " " + where_; }
    bool busy() const final { return static_cast<bool>(done_); }
    void cancel(const std::string& why) final;
    std::string closing_note() const final;

  protected:
    // Runs `request` on the request thread: a LinkError (or any exception) ends it with its
    // text. Throws std::logic_error while another request runs.
    void start(std::function<JobOutcome()> request, Done done);
    // Each subclass's destructor calls it first: the request thread is joined while the
    // subclass's members are still there.
    void finish_requests();
    // On the request thread: throws LinkError("stopped") once cancelled or stopping.
    void check_stop() const;
    bool stop_asked() const { return stopping_; }
    // Waits `how_long` unless cancelled meanwhile (then throws as check_stop).
    void pause(std::chrono::milliseconds how_long) const;
    // While one lives, a print of the box's runs on the host: a stop leaves it there, and
    // closing_note says so.
    class PrintingOnHost {
      public:
        explicit PrintingOnHost(HostLink& link) : link_(link) { link_.printing_ = true; }
        PrintingOnHost(const PrintingOnHost&) = delete;
        PrintingOnHost& operator=(const PrintingOnHost&) = delete;
        ~PrintingOnHost() { link_.printing_ = false; }

      private:
        HostLink& link_;
    };
    // What the host says of the box's print at one poll: under way (printing, paused, ...), or
    // over with its outcome; `state` is the host's own word, for an error line.
    struct PrintReport {
        bool printing = false;
        std::optional<JobOutcome> over;
        std::string state;
    };
    // On the request thread, once the print is started: polls the host every `poll_interval`
    // until `poll` (given whether the print was seen under way) says it is over. A print the
    // host has not been seen running within `start_timeout` is a LinkError ("the print never
    // started on the host (idle)"). The host's print is the box's meanwhile (PrintingOnHost).
    JobOutcome follow_print(std::chrono::milliseconds poll_interval,
                            std::chrono::milliseconds start_timeout,
                            const std::function<PrintReport(bool seen_printing)>& poll);
    const net::Url& url() const { return url_; }
    hal::HttpClient& http_client() const;
    const Log& log() const { return log_; }

  private:
    void finished();

    std::string name_;
    net::Url url_;
    std::string where_;
    hal::HttpClient* http_ = nullptr;
    Log log_;
    Done done_;
    std::string cancelled_;
    std::atomic<bool> stopping_{false};
    std::atomic<bool> printing_{false};
    bool left_a_print_ = false;  // the last request was cancelled while the host printed
    std::unique_ptr<hal::BackgroundJob<JobOutcome>> job_;
};

// What every host spoken to over HTTP is given: where it is, how long it may take to reply, how
// often a print of the box's is polled, and the job's file name on the host.
struct HttpHostSettings {
    net::Url url;
    std::chrono::milliseconds reply_timeout{30000};
    std::chrono::milliseconds poll_interval{250};
    std::string job_file_name = "calbox-target.gcode";
};

// A link to a host over HTTP whose requests share one session (a socket, a session key, the
// markers' count), used on the request thread only. `Session` is the link's own type, complete
// where the link's functions are defined; its `command(lines)` sends the lines and returns what
// the printer answered. The link makes its session in its constructor and calls
// finish_requests() first in its destructor. A link is declared
//   struct XSession;
//   class XLink final : public HttpSessionLink<XSettings, XSession> { ... friend XSession; };
//   extern template class HttpSessionLink<XSettings, XSession>;
// and its source, once XSession is defined: template class HttpSessionLink<XSettings, XSession>;
template <class Settings, class Session>
class HttpSessionLink : public HostLink {
  public:
    HttpSessionLink(const HttpSessionLink&) = delete;
    HttpSessionLink& operator=(const HttpSessionLink&) = delete;

    void send_commands(const std::vector<std::string>& lines, Done done) override;

  protected:
    // `name`: the host's kind, for the log ("duet").
    HttpSessionLink(std::string name, Settings settings, hal::HttpClient& http, Log log)
        : HostLink(std::move(name), settings.url, http, std::move(log)),
          settings_(std::move(settings)) {}
    ~HttpSessionLink() override = default;

    // `request`, given the session, on the request thread (as HostLink::start).
    void start_in_session(std::function<JobOutcome(Session&)> request, Done done) {
        start(
            [session = session_.get(), request = std::move(request)] { return request(*session); },
            std::move(done));
    }

    Settings settings_;
    std::unique_ptr<Session> session_;
};

// Defined here, instantiated once in each link's source (where its Session is complete): each
// link's header declares `extern template class HttpSessionLink<...>`, its source instantiates it.
template <class Settings, class Session>
void HttpSessionLink<Settings, Session>::send_commands(const std::vector<std::string>& lines,
                                                       Done done) {
    start_in_session(
        [lines](Session& s) {
            return JobOutcome{true, {}, s.command(lines), {}};
        },
        std::move(done));
}

}  // namespace calbox::firmware
