#pragma once
// What the network gives the appliance, opened by a board (board::network()) as it opens ports
// and Modbus roles: an HTTP client, listeners, MQTT sessions, and the password hasher of the web
// page's password.
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "hal/http.hpp"
#include "hal/mqtt.hpp"
#include "hal/password.hpp"

namespace calbox::hal {

// A server certificate as an owner checks it against what the browser shows.
struct CertificateFacts {
    std::string sha256_fingerprint;  // of the DER form, "AB:CD:...", as browsers show it
    std::string subject;             // its common name
    std::int64_t not_after_unix_s = 0;
};

// What Certificates::check throws when a file of the pair is not there at all.
class CertificateMissing : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

class Certificates {
  public:
    virtual ~Certificates() = default;
    // A new self-signed certificate for `names` (host names and IP addresses; the first is its
    // common name), valid `valid_days` from now, written to the two files (the key readable by
    // its owner only; each written whole or not at all). Throws std::runtime_error.
    virtual void make_self_signed(const ServerTls& files, const std::vector<std::string>& names,
                                  int valid_days) = 0;
    // Reads and checks the pair: both load, the key is the certificate's. Throws
    // CertificateMissing for a file that is not there, std::runtime_error naming the file and
    // what is wrong with it for the rest.
    virtual CertificateFacts check(const ServerTls& files) = 0;
};

// A conversation in text lines over TCP (a telnet-style service: LinuxCNC's linuxcncrsh),
// blocking, each wait bounded; for a link's request thread.
class TextConnection {
  public:
    virtual ~TextConnection() = default;
    // Writes `line` and "\r\n". Throws NetworkError when the connection is gone.
    virtual void write_line(const std::string& line) = 0;
    // The next line, its "\r\n" dropped; empty when none came within `timeout`. Throws
    // NetworkError when the peer closes.
    virtual std::optional<std::string> read_line(std::chrono::milliseconds timeout) = 0;
};

class Network {
  public:
    virtual ~Network() = default;
    virtual HttpClient& http() = 0;
    // Serves on `port` of `address` (an IP address; port 0 takes a free one), over TLS when
    // `tls` is given (its files checked by certificates().check first). Throws NetworkError when
    // it cannot listen or the files do not load.
    virtual std::unique_ptr<HttpListener> listen(const std::string& address, int port,
                                                 HttpHandlers handlers, ServerLimits limits,
                                                 const std::optional<ServerTls>& tls) = 0;
    virtual Certificates& certificates() = 0;
    // Starts connecting at once. Throws std::runtime_error when the session cannot start or its
    // login cannot be tried at all (the password's file missing, empty or readable by others; a
    // CA file TLS cannot load).
    virtual std::unique_ptr<MqttSession> mqtt(const std::string& client_id,
                                              const MqttBroker& broker, MqttWill will,
                                              MqttCallbacks callbacks) = 0;
    virtual PasswordHasher& passwords() = 0;
    // Connects to `port` of `host` (a name or an address) within `timeout`. Throws NetworkError
    // naming the host, the port and why.
    virtual std::unique_ptr<TextConnection> connect_text(const std::string& host, int port,
                                                         std::chrono::milliseconds timeout) = 0;
};

}  // namespace calbox::hal
