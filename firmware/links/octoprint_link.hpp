#pragma once
// The machine link to a Marlin printer through OctoPrint, which holds the printer's serial port.
// OctoPrint gives a command no reply of its own: the box sends the commands bracketed by two
// markers Marlin echoes (M118), and reads what the printer said between them from the push
// socket's terminal logs. A job is uploaded with print=true and followed through /api/job.
// Settings go as over serial (M503, M665/M666/M500 and the read-back), as commands. The API key
// goes in the X-Api-Key header (and the socket's auth is a passive login's session) and nowhere
// else.
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "firmware/links/host_link.hpp"
#include "hal/http.hpp"
#include "hal/log.hpp"

namespace calbox::firmware {

struct OctoPrintSettings {
    net::Url url;
    std::string api_key;   // empty: none yet (every request says so)
    std::string key_file;  // where it is kept, for that message
    std::chrono::milliseconds reply_timeout{30000};
    std::chrono::milliseconds poll_interval{250};
    std::string job_file_name = "calbox-target.gcode";
};

class OctoPrintLink final : public HostLink {
  public:
    OctoPrintLink(OctoPrintSettings settings, hal::HttpClient& http, Log log);
    ~OctoPrintLink() override;
    OctoPrintLink(const OctoPrintLink&) = delete;
    OctoPrintLink& operator=(const OctoPrintLink&) = delete;

    void run_job(const std::vector<std::string>& lines, Done done) override;
    void send_commands(const std::vector<std::string>& lines, Done done) override;

    struct Session;  // the push socket and the markers' count, on the request thread only

  private:
    OctoPrintSettings settings_;
    std::unique_ptr<Session> session_;
};

// OctoPrint's application keys (its appkeys plugin): asks the host for a key for calbox, which
// its owner allows in OctoPrint's page; `wait` polls until then. Returns the key; throws
// LinkError when the owner denies it, the host lacks the plugin, or `wait` passes.
std::string request_octoprint_key(hal::HttpClient& http, const net::Url& url,
                                  const std::string& user, std::chrono::milliseconds wait,
                                  const hal::Log& log);

}  // namespace calbox::firmware
