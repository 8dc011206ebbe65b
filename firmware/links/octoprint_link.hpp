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

struct OctoPrintSettings : HttpHostSettings {
    std::string api_key;   // empty: none yet (every request says so)
    std::string key_file;  // where it is kept, for that message
};

struct OctoPrintSession;  // the push socket and the markers' count

class OctoPrintLink final : public HttpSessionLink<OctoPrintSettings, OctoPrintSession> {
  public:
    OctoPrintLink(OctoPrintSettings settings, hal::HttpClient& http, Log log);
    ~OctoPrintLink() override;

    void run_job(const std::vector<std::string>& lines, Done done) override;

  private:
    friend OctoPrintSession;
    // What OctoPrint's /api/job answer says of the job uploaded as `ours` (`seen`: it was seen
    // printing); throws LinkError for an answer that is not JSON or a failed print.
    static PrintReport job_report(const std::string& api_job_body, const std::string& ours,
                                  bool seen);
};

extern template class HttpSessionLink<OctoPrintSettings, OctoPrintSession>;

// OctoPrint's application keys (its appkeys plugin): asks the host for a key for calbox, which
// its owner allows in OctoPrint's page; `wait` polls until then. Returns the key; throws
// LinkError when the owner denies it, the host lacks the plugin, or `wait` passes.
std::string request_octoprint_key(hal::HttpClient& http, const net::Url& url,
                                  const std::string& user, std::chrono::milliseconds wait,
                                  const hal::Log& log);

}  // namespace calbox::firmware
