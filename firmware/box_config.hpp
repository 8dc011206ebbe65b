#pragma once
// The box's configuration file (calbox run --config FILE): today its [modbus] table; the
// console's configuration store ("The appliance 2") grows from here. Options given on the
// command line win over the file.
#include <cstdint>
#include <string>

namespace calbox::firmware {

struct ModbusConfig {
    std::string server;      // "tcp:HOST:PORT" or "rtu:DEVICE:BAUD"; empty: no server
    std::string client;      // the controller the results are written to; empty: none
    std::string client_map;  // a map file (value_name = register); empty: the whole block from 0
    std::string word_order = "abcd";
    std::uint32_t response_timeout_ms = 1000;
    std::uint32_t byte_timeout_ms = 500;
};

struct BoxConfig {
    ModbusConfig modbus;
};

// Strict: a wrong type, a value out of range, an endpoint or word order that does not parse or
// an unknown key is a models::MachineFileError naming the file, the table and the key.
BoxConfig read_box_config(const std::string& text, const std::string& file);

}  // namespace calbox::firmware
