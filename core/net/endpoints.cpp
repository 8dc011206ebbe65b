#include "core/net/endpoints.hpp"

#include <arpa/inet.h>

#include <cctype>
#include <stdexcept>

namespace calbox::net {
namespace {

bool is_ip_address(const std::string& host) {
    unsigned char bytes[16];
    return ::inet_pton(AF_INET, host.c_str(), bytes) == 1 ||
           ::inet_pton(AF_INET6, host.c_str(), bytes) == 1;
}

int modbus_number(const std::string& text, const std::string& what, const std::string& whole) {
    std::size_t used = 0;
    int value = 0;
    try {
        value = std::stoi(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used != text.size() || text.empty()) {
        throw std::invalid_argument("modbus endpoint '" + whole + "': " + what + " '" + text +
                                    "' is not a number");
    }
    return value;
}

}  // namespace

HostPort parse_host_port(const std::string& text, bool names) {
    const auto colon = text.rfind(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == text.size())
        throw std::invalid_argument("'" + text + "' is not HOST:PORT");
    HostPort hp;
    hp.host = text.substr(0, colon);
    if (hp.host.size() > 2 && hp.host.front() == '[' && hp.host.back() == ']')
        hp.host = hp.host.substr(1, hp.host.size() - 2);
    const std::string port = text.substr(colon + 1);
    if (port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
        std::stoi(port) > 65535)
        throw std::invalid_argument("'" + text + "': the port must be 0 to 65535");
    hp.port = std::stoi(port);
    if (hp.host == "localhost") hp.host = "127.0.0.1";
    const bool ip = is_ip_address(hp.host);
    if (!ip && !names)
        throw std::invalid_argument("'" + text +
                                    "': the host must be an IP address (0.0.0.0 for "
                                    "every interface)");
    if (!ip && hp.host.find_first_of(" /\t") != std::string::npos)
        throw std::invalid_argument("'" + text + "' is not HOST:PORT");
    return hp;
}

Url parse_url(const std::string& text) {
    Url url;
    const std::size_t colon = text.find("://");
    if (colon == std::string::npos)
        throw std::invalid_argument("'" + text + "' is not a URL (http://HOST:PORT)");
    url.scheme = text.substr(0, colon);
    for (auto& c : url.scheme) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (url.scheme != "http" && url.scheme != "ws" && url.scheme != "https" && url.scheme != "wss")
        throw std::invalid_argument("'" + text + "': the scheme must be http, https, ws or wss");
    std::string rest = text.substr(colon + 3);
    const std::size_t slash = rest.find('/');
    url.path = slash == std::string::npos ? "/" : rest.substr(slash);
    std::string authority = slash == std::string::npos ? rest : rest.substr(0, slash);
    if (authority.find('@') != std::string::npos)
        throw std::invalid_argument("'" + text +
                                    "': no user or password in the URL (the key goes in its file)");
    const std::size_t port_at = authority.rfind(':');
    if (port_at != std::string::npos && authority.find(']') == std::string::npos) {
        url.port = authority.substr(port_at + 1);
        authority.resize(port_at);
    } else {
        url.port = url.tls() ? "443" : "80";
    }
    url.host = authority;
    if (url.host.empty()) throw std::invalid_argument("'" + text + "': no host");
    int port = 0;
    for (char c : url.port) {
        if (!std::isdigit(static_cast<unsigned char>(c)))
            throw std::invalid_argument("'" + text + "': the port is not a number");
        port = port * 10 + (c - '0');
        if (port > 65535) break;
    }
    if (url.port.empty() || port < 1 || port > 65535)
        throw std::invalid_argument("'" + text + "': the port must be 1 to 65535");
    return url;
}

std::string ModbusEndpoint::text() const {
    if (kind == Kind::tcp) return "tcp:" + host + ":" + std::to_string(port);
    return "rtu:" + device + ":" + std::to_string(baud);
}

std::string ModbusEndpoint::describe() const {
    return "modbus " + text();
}

ModbusEndpoint parse_modbus_endpoint(const std::string& text) {
    const auto first = text.find(':');
    const auto last = text.rfind(':');
    if (first == std::string::npos || first == last) {
        throw std::invalid_argument("modbus endpoint '" + text +
                                    "' is not tcp:HOST:PORT or rtu:DEVICE:BAUD");
    }
    const std::string kind = text.substr(0, first);
    const std::string middle = text.substr(first + 1, last - first - 1);
    const std::string number = text.substr(last + 1);
    ModbusEndpoint e;
    if (kind == "tcp") {
        e.kind = ModbusEndpoint::Kind::tcp;
        e.host = middle;
        e.port = modbus_number(number, "port", text);
        if (e.port < 0 || e.port > 65535) {
            throw std::invalid_argument("modbus endpoint '" + text + "': port out of range");
        }
    } else if (kind == "rtu") {
        e.kind = ModbusEndpoint::Kind::rtu;
        e.device = middle;
        e.baud = modbus_number(number, "baud rate", text);
        if (e.baud <= 0) throw std::invalid_argument("modbus endpoint '" + text + "': bad baud");
    } else {
        throw std::invalid_argument("modbus endpoint '" + text + "': '" + kind +
                                    "' is not tcp or rtu");
    }
    if (middle.empty()) {
        throw std::invalid_argument("modbus endpoint '" + text + "': no host or device");
    }
    return e;
}

}  // namespace calbox::net
