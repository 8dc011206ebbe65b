#pragma once
// The machine link to a Klipper printer through its Moonraker host, which owns the printer's
// serial port: JSON-RPC over Moonraker's websocket (server.connection.identify first), commands
// through printer.gcode.script with their text from notify_gcode_response, a job uploaded to the
// host and started there (server.files.upload, printer.print.start) and followed by print_stats,
// printer.cfg read and replaced through the file API and taken by FIRMWARE_RESTART, the settings
// in force from configfile.settings. The API key goes in the X-Api-Key header and nowhere else.
// Each request runs on a thread of its own; its `done` comes back through the event loop.
#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "firmware/links/host_link.hpp"
#include "hal/http.hpp"

namespace calbox::firmware {

// poll_interval: print_stats, and printer.info while Klipper restarts.
struct MoonrakerSettings : HttpHostSettings {
    std::string api_key;  // empty: a host that asks for none (trusted clients)
    std::chrono::milliseconds restart_timeout{60000};
};

struct MoonrakerSession;  // the websocket and its request ids

class MoonrakerLink final : public HttpSessionLink<MoonrakerSettings, MoonrakerSession> {
  public:
    MoonrakerLink(MoonrakerSettings settings, hal::HttpClient& http, Log log);
    ~MoonrakerLink() override;

    void run_job(const std::vector<std::string>& lines, Done done) override;

    bool has_config_file() const override { return true; }
    void read_config_file(Done done) override;
    void replace_config_file(const std::string& text, const std::string& expected_now,
                             Done done) override;
    void save_config_after(const std::vector<std::string>& lines, Done done) override;
    void read_settings_in_force(Done done) override;

  private:
    friend MoonrakerSession;
};

extern template class HttpSessionLink<MoonrakerSettings, MoonrakerSession>;

}  // namespace calbox::firmware
