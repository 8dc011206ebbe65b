#pragma once
// The machine link to a RepRapFirmware printer on the network through a Duet's own web API. A
// standalone board: rr_connect with the board's password for a session key, rr_gcode and
// rr_reply for commands (a batch ended by a marker M118 echoes, so that the box knows where its
// replies end), rr_upload with the file's CRC32 and M32 for a job, followed through the object
// model's state and job. A board with an SBC (rr_connect answers 404 there, as Duet Web Control
// finds out): DuetSoftwareFramework's /machine/connect, /machine/code (which answers with the
// code's reply), PUT /machine/file and /machine/model. Settings go as over serial (M665, M666,
// M500 and the read-back). The password is sent to the connect request and nowhere else; the
// session is closed when the link goes.
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "firmware/links/host_link.hpp"
#include "hal/http.hpp"

namespace calbox::firmware {

struct DuetSettings : HttpHostSettings {
    std::string password;  // the board's (M551); empty: a board without one
};

struct DuetSession;  // the session key and the markers' count

class DuetLink final : public HttpSessionLink<DuetSettings, DuetSession> {
  public:
    DuetLink(DuetSettings settings, hal::HttpClient& http, Log log);
    ~DuetLink() override;

    void run_job(const std::vector<std::string>& lines, Done done) override;

  private:
    friend DuetSession;
};

extern template class HttpSessionLink<DuetSettings, DuetSession>;

// A query parameter's value, percent-encoded (RFC 3986's unreserved characters as they are).
std::string url_encoded(const std::string& text);

}  // namespace calbox::firmware
