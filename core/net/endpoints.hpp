#pragma once
// Where a peer is, as the owner writes it: a URL, HOST:PORT, a Modbus endpoint. Parsed once into
// a typed value; each parser throws std::invalid_argument naming what is wrong. Text only: no
// name is looked up here.
#include <string>

namespace calbox::net {

// "http://host:port/path", "https://...", "ws://..." or "wss://...".
struct Url {
    std::string scheme, host, port, path;
    // Over TLS: the certificate authorities that vouch for the host, a PEM file (empty: the
    // system's). The host's certificate must name the URL's host.
    std::string ca_file;
    bool tls() const { return scheme == "https" || scheme == "wss"; }
    std::string origin() const { return scheme + "://" + host + ":" + port; }
};
Url parse_url(const std::string& text);

// "HOST:PORT" ("[::1]:8080" for IPv6), the port 0 to 65535. With `names` false the host must
// be an IP address ("localhost" is 127.0.0.1): a server binds to one.
struct HostPort {
    std::string host;
    int port = 0;
};
HostPort parse_host_port(const std::string& text, bool names);

// "tcp:HOST:PORT" or "rtu:DEVICE:BAUD" (8 data bits, no parity, one stop bit).
struct ModbusEndpoint {
    enum class Kind { tcp, rtu };
    Kind kind = Kind::tcp;
    std::string host;              // tcp
    int port = 502;                // tcp
    std::string device;            // rtu
    int baud = 19200;              // rtu
    int unit_id = 1;               // rtu: the server's address; tcp: the unit identifier sent
    std::string text() const;      // as it is written: "tcp:HOST:PORT", "rtu:DEVICE:BAUD"
    std::string describe() const;  // "modbus " and the text, for the log
};
ModbusEndpoint parse_modbus_endpoint(const std::string& text);

}  // namespace calbox::net
