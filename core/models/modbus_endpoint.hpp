#pragma once
// Where a Modbus peer is, as the configuration and the command line name it: parsed once into
// this typed value, then handed to the board that opens it.
#include <cstdint>
#include <string>

namespace calbox::models {

// "tcp:HOST:PORT" or "rtu:DEVICE:BAUD" (8 data bits, no parity, one stop bit).
struct ModbusEndpoint {
    enum class Kind { tcp, rtu };
    Kind kind = Kind::tcp;
    std::string host;    // tcp
    int port = 502;      // tcp
    std::string device;  // rtu
    int baud = 19200;    // rtu
    int unit_id = 1;     // rtu: the server's address; tcp: the unit identifier sent
    std::string describe() const;
};
ModbusEndpoint parse_modbus_endpoint(const std::string& text);  // throws std::invalid_argument

struct ModbusTimeouts {
    std::uint32_t response_ms = 1000;  // the whole reply (client) or a frame once begun (both)
    std::uint32_t byte_ms = 500;       // between two bytes of one frame
};

}  // namespace calbox::models
