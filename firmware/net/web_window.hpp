#pragma once
// The box's own web page (docs/network.md): status updated live over a websocket, the live view
// with the set-up guide, the last cycle's pictures and every record, the configuration, the
// button's actions, the drift history and /metrics. A window on the cycle like the display: it
// reads through the loop's inbox and acts only through the console's commands, so that the page,
// the button and the console do one thing one way. Served by a hal::HttpListener.
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>

#include "firmware/loop/event_loop.hpp"
#include "firmware/net/live_view.hpp"
#include "firmware/settings/settings_table.hpp"
#include "hal/clock.hpp"
#include "hal/network.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

// What one client may ask before it is refused (429), and the server's own limits.
// The box's own web page (docs/network.md): off while `listen` is empty. Anything that changes
// state needs the password, kept only as its hash (hal/password.hpp).
struct WebSettings {
    std::string listen;  // HOST:PORT, an IP address to bind
    std::string password_hash;
    // TLS (firmware/net/web_tls.hpp): where, and the certificate's files (both empty: the box's
    // own, self-signed).
    std::string tls_listen;
    std::string tls_cert, tls_key;
};

// The web page's table of the configuration: [web].
SettingsTable<WebSettings> web_settings_table();

struct WebLimits {
    double requests_per_second = 20;  // each client's steady rate
    double burst = 60;                // and what it may ask at once
    int wrong_passwords = 5;          // in a row, then the client waits
    std::chrono::seconds wrong_password_wait{30};
    std::uint64_t max_body_bytes = 64 << 10;  // a configuration change is a few dozen bytes
    int max_connections = 32;
    std::chrono::milliseconds idle_timeout{15000};
    std::chrono::milliseconds loop_answer{5000};  // the loop answers within it, else 503
    int live_width_px = 960;
};

// A refusal as the page gives it (its plain port too): the status and {"error": MESSAGE}.
hal::ServerResponse error_answer(int status, const std::string& message, hal::Headers headers = {});

// The server's limits the page asks for (its plain port's redirects too).
hal::ServerLimits server_limits(const WebLimits& limits);

struct WebWindowContext {
    LoopInbox& inbox;
    hal::Storage& records;  // the data directory: read from the server's threads
    hal::Clock& clock;      // the flood limit's
    LatestFrame& frames;    // the camera's newest frame (Cycle::on_frame)
    hal::Network& network;  // its listener and the password's hasher
    // The files the cycle's mode keeps beside the records (CycleMode::kept_files), served
    // with them.
    std::vector<std::string> kept_files;
    // Each called on the loop's thread:
    std::function<std::string(const std::string& line)> console;  // a console line's reply
    std::function<nlohmann::json()> status;                       // BoxNews::status, the log
    std::function<nlohmann::json()> history;
    std::function<std::string()> metrics;
    std::function<std::string()> password_hash;  // the configuration's web.password
    std::function<bool()> preview;               // Cycle::preview
    std::function<LiveGuide()> guide;
    std::function<std::optional<std::string>()> kept_result;  // the correction in force's text
};

class WebWindow {
  public:
    // Listens at host:port (port 0: a free one), over TLS with `tls`; throws hal::NetworkError
    // when it cannot.
    WebWindow(WebWindowContext context, const std::string& host, int port, WebLimits limits = {},
              const std::optional<hal::ServerTls>& tls = std::nullopt);
    WebWindow(const WebWindow&) = delete;
    WebWindow& operator=(const WebWindow&) = delete;
    ~WebWindow();
    int port() const;
    // An event to every page open (the status changed, a log line): any thread.
    void push(const std::string& event_json);

  private:
    struct Peer {
        double tokens = 0;
        std::chrono::nanoseconds refilled{0};
        int wrong_passwords = 0;
        std::chrono::nanoseconds locked_until{0};
    };
    hal::ServerResponse answer(const hal::ServerRequest& request);
    hal::ServerResponse route(const hal::ServerRequest& request, const std::string& path,
                              const std::string& query);
    hal::ServerResponse post(const hal::ServerRequest& request, const std::string& path);
    // POST /api/action and /api/config's JSON object, as the console line it asks for.
    hal::ServerResponse post_action(const nlohmann::json& body);
    hal::ServerResponse post_config(const nlohmann::json& body);
    hal::ServerResponse live(const std::string& query);
    // GET /api/place?job=job-NAME.EXT&work_zero=X,Y: the job's outline on the bed.
    hal::ServerResponse place(const std::string& query);
    hal::ServerResponse record(const std::string& name, const std::string& query);
    // Empty when the request may change state; else the refusal.
    std::optional<hal::ServerResponse> refuse_password(const hal::ServerRequest& request);
    bool take_token(const std::string& peer);
    // On the loop's thread, within limits_.loop_answer; throws Busy otherwise.
    template <class T>
    T on_loop(std::function<T()> job);
    // A console line's reply on the loop, as HTTP: 200 with its JSON, or 409 with its error.
    hal::ServerResponse console_answer(const std::string& line);

    WebWindowContext c_;
    WebLimits limits_;
    std::mutex peers_mutex_;
    std::map<std::string, Peer> peers_;  // under peers_mutex_
    SharedLiveView live_view_;
    std::unique_ptr<hal::HttpListener> server_;  // last: its threads use the rest
};

}  // namespace calbox::firmware
