#include "core/models/modbus_endpoint.hpp"

#include <stdexcept>

namespace calbox::models {
namespace {

int parse_int(const std::string& text, const std::string& what, const std::string& whole) {
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

std::string ModbusEndpoint::describe() const {
    if (kind == Kind::tcp) return "modbus tcp:" + host + ":" + std::to_string(port);
    return "modbus rtu:" + device + ":" + std::to_string(baud);
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
        e.port = parse_int(number, "port", text);
        if (e.port < 0 || e.port > 65535) {
            throw std::invalid_argument("modbus endpoint '" + text + "': port out of range");
        }
    } else if (kind == "rtu") {
        e.kind = ModbusEndpoint::Kind::rtu;
        e.device = middle;
        e.baud = parse_int(number, "baud rate", text);
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

}  // namespace calbox::models
