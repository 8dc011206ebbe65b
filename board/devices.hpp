#pragma once
// Every board's devices, one type (as ArduPilot's AP_HAL::HAL is one struct of device pointers
// that SITL fills like any board): the appliance is built from it without knowing which board
// filled it. Beside it, the devices every board opens the same way by name, for the composition
// root: the clock, the data directory, a console's port, the Modbus endpoints, photos from files.
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "core/net/endpoints.hpp"
#include "hal/camera.hpp"
#include "hal/clock.hpp"
#include "hal/display.hpp"
#include "hal/lines.hpp"
#include "hal/log.hpp"
#include "hal/network.hpp"
#include "hal/register_link.hpp"
#include "hal/serial_port.hpp"
#include "hal/storage.hpp"
#include "hal/supervisor.hpp"

namespace calbox::board {

struct Devices {
    std::unique_ptr<hal::Camera> camera;
    std::unique_ptr<hal::Lines> lines;
    std::unique_ptr<hal::Display> display;
    std::unique_ptr<hal::SerialPort> machine;  // the machine's link
    std::unique_ptr<hal::Network> network;
};

// CLOCK_MONOTONIC, its timers timerfds.
std::unique_ptr<hal::Clock> monotonic_clock();
// A directory of files replaced atomically (a power cut leaves the old file or the new).
std::unique_ptr<hal::Storage> data_directory(const std::filesystem::path& directory);
// Photos from image files (a directory, or a glob), one per frame in name order.
std::unique_ptr<hal::Camera> photo_files(const std::string& source);

// A console's port: a serial device, a new pseudo-terminal (`path` its other end), or standard
// input and output. Each throws std::runtime_error with the system's reason.
std::unique_ptr<hal::SerialPort> serial_port(const std::string& device, int baud);
struct Pty {
    std::unique_ptr<hal::SerialPort> port;
    std::string path;
};
Pty pseudo_terminal();
std::unique_ptr<hal::SerialPort> standard_io();
// A line of the box's log on standard error, "calbox: LINE"; when standard error is the journal's
// stream (systemd's JOURNAL_STREAM names its device and inode) with its level's prefix ("<3>" for
// an error), which the journal files it under and which elsewhere would be noise.
void log_to_standard_error(hal::LogLevel level, const std::string& line);
// The service manager the box runs under (systemd's notification socket, when it gives one).
std::unique_ptr<hal::Supervisor> service_supervisor();

// The network: HTTP clients and listeners, MQTT sessions, the password hasher.
std::unique_ptr<hal::Network> network();

// The box's Modbus roles over an endpoint: its own registers for a PLC, and a controller's it
// writes its results to. Throw std::runtime_error naming the endpoint.
struct RegisterTables {
    int coils = 0, discrete_inputs = 0, holding_registers = 0, input_registers = 0;
};
struct RegisterServer {
    std::unique_ptr<hal::RegisterServer> server;
    int port = 0;  // the TCP port it listens on (useful with port 0)
};
RegisterServer register_server(const net::ModbusEndpoint& endpoint, RegisterTables tables,
                               const hal::ModbusTimeouts& timeouts, hal::Log log);
std::unique_ptr<hal::RegisterLink> register_client(const net::ModbusEndpoint& endpoint,
                                                   const hal::ModbusTimeouts& timeouts);

}  // namespace calbox::board
