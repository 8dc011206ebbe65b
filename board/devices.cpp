#include "board/devices.hpp"

#include "drivers/file_camera.hpp"
#include "drivers/file_storage.hpp"
#include "drivers/modbus_link.hpp"
#include "drivers/network.hpp"
#include "drivers/pty_port.hpp"
#include "drivers/termios_port.hpp"
#include "drivers/timerfd_clock.hpp"

namespace calbox::board {

std::unique_ptr<hal::Clock> monotonic_clock() {
    return std::make_unique<drivers::TimerfdClock>();
}

std::unique_ptr<hal::Storage> data_directory(const std::filesystem::path& directory) {
    return std::make_unique<drivers::FileStorage>(directory);
}

std::unique_ptr<hal::Camera> photo_files(const std::string& source) {
    return std::make_unique<drivers::FileCamera>(source);
}

std::unique_ptr<hal::Network> network() {
    return drivers::system_network();
}

std::unique_ptr<hal::SerialPort> serial_port(const std::string& device, int baud) {
    return std::make_unique<drivers::TermiosPort>(device, baud);
}

Pty pseudo_terminal() {
    auto pty = std::make_unique<drivers::PtyPort>();
    std::string path = pty->slave_path();
    return {std::move(pty), std::move(path)};
}

std::unique_ptr<hal::SerialPort> standard_io() {
    return std::make_unique<drivers::StdioPort>();
}

RegisterServer register_server(const net::ModbusEndpoint& endpoint, RegisterTables tables,
                               const hal::ModbusTimeouts& timeouts,
                               std::function<void(const std::string&)> log) {
    auto server = std::make_unique<drivers::ModbusServer>(
        endpoint,
        drivers::ModbusServer::Tables{tables.coils, tables.discrete_inputs,
                                      tables.holding_registers, tables.input_registers},
        timeouts, std::move(log));
    const int port = server->port();
    return {std::move(server), port};
}

std::unique_ptr<hal::RegisterLink> register_client(const net::ModbusEndpoint& endpoint,
                                                   const hal::ModbusTimeouts& timeouts) {
    return std::make_unique<drivers::ModbusClient>(endpoint, timeouts);
}

}  // namespace calbox::board
