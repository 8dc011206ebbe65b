#include "board/devices.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "drivers/file_camera.hpp"
#include "drivers/file_storage.hpp"
#include "drivers/modbus_link.hpp"
#include "drivers/network.hpp"
#include "drivers/pty_port.hpp"
#include "drivers/systemd_supervisor.hpp"
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
                               const hal::ModbusTimeouts& timeouts, hal::Log log) {
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

namespace {

bool standard_error_is_journal() {
    const char* stream = std::getenv("JOURNAL_STREAM");  // "DEVICE:INODE", both decimal
    if (stream == nullptr) return false;
    struct stat error_stream {};
    if (::fstat(STDERR_FILENO, &error_stream) != 0) return false;
    return std::string(stream) ==
           std::to_string(error_stream.st_dev) + ":" + std::to_string(error_stream.st_ino);
}

}  // namespace

void log_to_standard_error(hal::LogLevel level, const std::string& line) {
    static const bool to_journal = standard_error_is_journal();
    if (to_journal)
        std::fprintf(stderr, "<%d>calbox: %s\n", static_cast<int>(level), line.c_str());
    else
        std::fprintf(stderr, "calbox: %s\n", line.c_str());
}

std::unique_ptr<hal::Supervisor> service_supervisor() {
    return std::make_unique<drivers::SystemdSupervisor>();
}

}  // namespace calbox::board
