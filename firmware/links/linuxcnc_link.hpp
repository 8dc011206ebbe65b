#pragma once
// The machine link to LinuxCNC through its linuxcncrsh server (a telnet-style text protocol on
// TCP, port 5007 by default), as LinuxCNC's own remote shell documents it: HELLO with the
// connect password, SET ENABLE with the enable password, SET MODE MDI, SET WAIT_MODE DONE (SET
// SET_WAIT on LinuxCNC 2.8), then each G-code line by SET MDI, its ACK only once the line is done
// and its NAK read with GET ERROR. LinuxCNC reads no G-code over a serial port; a job runs line by
// line in MDI. Each request is one connection of its own, closed when it ends.
#include <chrono>
#include <string>
#include <vector>

#include "firmware/links/host_link.hpp"
#include "hal/network.hpp"

namespace calbox::firmware {

struct LinuxCncSettings {
    std::string host;
    int port = 5007;
    // linuxcncrsh's defaults (--connectpw, --enablepw) unless the key file gives others.
    std::string connect_password = "EMC";
    std::string enable_password = "EMCTOO";
    std::chrono::milliseconds connect_timeout{5000};
    // A line's, from its SET MDI to its ACK (the motion done).
    std::chrono::milliseconds reply_timeout{30000};
};

// In a request's lines, one that starts so is a query of linuxcncrsh's own ("get pos_offset X"),
// sent as it is; its answer ("POS_OFFSET X 12.500000") is one of the outcome's replies. Every
// other line is G-code, sent by MDI.
inline constexpr const char* kLinuxCncQuery = "get ";

// The longest G-code line linuxcncrsh takes: it reads a command into 256 bytes.
inline constexpr std::size_t kLinuxCncLongestLine = 240;

class LinuxCncLink final : public HostLink {
  public:
    LinuxCncLink(LinuxCncSettings settings, hal::Network& network, Log log);
    ~LinuxCncLink() override;
    LinuxCncLink(const LinuxCncLink&) = delete;
    LinuxCncLink& operator=(const LinuxCncLink&) = delete;

    // Every line by MDI, in order, each done before the next; no query.
    void run_job(const std::vector<std::string>& lines, Done done) override;
    void send_commands(const std::vector<std::string>& lines, Done done) override;

  private:
    class Talk;
    JobOutcome converse(const std::vector<std::string>& lines, bool queries);

    LinuxCncSettings settings_;
    hal::Network& network_;
};

}  // namespace calbox::firmware
