#pragma once
// The box's windows on the network, wired to the cycle as `calbox run` wires them: the web page
// and MQTT where the configuration (or --web / --mqtt) says, both fed by BoxNews and acting only
// through the console's commands, from their own threads through the loop's inbox.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "firmware/console/console.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/loop/event_loop.hpp"
#include "firmware/net/box_news.hpp"
#include "firmware/net/live_view.hpp"
#include "firmware/net/web_tls.hpp"
#include "hal/clock.hpp"
#include "hal/network.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

class WebWindow;
class MqttReport;
struct WebLimits;
struct WebSettings;
struct MqttSettings;

struct BoxNetworkParts {
    EventLoop& loop;
    Cycle& cycle;
    Console& console;
    // The configuration's, as in force: the password's hash is read at each request.
    const WebSettings& web;
    const MqttSettings& mqtt;
    hal::Storage& data;    // the records the page serves
    std::string data_dir;  // its path: the page's self-signed certificate is kept there
    hal::Clock& clock;
    hal::Network& network;
    const LogBook& log_book;
    BoxNews& news;
    Cycle::Log log;
    std::string version;
    std::function<std::int64_t()> unix_now;  // the wall clock, for the history
};

class BoxNetwork {
  public:
    // Starts what the configuration asks for. Throws hal::NetworkError when the page cannot
    // listen where it is told; a broker that is not there is only logged (and retried).
    explicit BoxNetwork(BoxNetworkParts parts);
    BoxNetwork(BoxNetworkParts parts, const WebLimits& limits);
    BoxNetwork(const BoxNetwork&) = delete;
    BoxNetwork& operator=(const BoxNetwork&) = delete;
    ~BoxNetwork();

    // A log line: the page's log only (MQTT carries the state, not every line). The cycle's
    // states, prompts, ends and frames it hears for itself.
    void logged();
    int web_port() const;  // 0 without a page

  private:
    void changed();
    void cycle_ended(bool completed);
    nlohmann::json status(bool for_page) const;
    LiveGuide guide() const;
    ConsoleCommand web_tls_row();
    BoxNetworkParts p_;
    std::optional<WebTlsIdentity> tls_;
    LoopInbox inbox_;
    LatestFrame frames_;
    std::unique_ptr<WebWindow> web_;
    std::unique_ptr<hal::HttpListener> redirect_;  // the plain port while TLS is on
    std::unique_ptr<MqttReport> mqtt_;
    CycleSubscription listening_;
};

}  // namespace calbox::firmware
