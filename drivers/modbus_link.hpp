#pragma once
// Modbus over TCP or RTU with libmodbus 3.1: where the peer is, and the box's two roles.
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "core/net/endpoints.hpp"
#include "hal/background_job.hpp"
#include "hal/log.hpp"
#include "hal/notifier.hpp"
#include "hal/register_link.hpp"

typedef struct _modbus modbus_t;
typedef struct _modbus_mapping_t modbus_mapping_t;

namespace calbox::drivers {

using hal::ModbusTimeouts;
using net::ModbusEndpoint;

// The box as a Modbus server (a PLC reads and drives it): coils and holding registers the
// client may write, discrete inputs and input registers it reads. Serves on its own thread;
// libmodbus answers reads, out-of-range addresses (exception 2) and bad values (exception 3).
class ModbusServer final : public hal::RegisterServer {
  public:
    struct Tables {
        int coils = 0, discrete_inputs = 0, holding_registers = 0, input_registers = 0;
    };
    using Log = hal::Log;
    // Listens (TCP, any number of clients) or opens the serial device (RTU). Throws
    // std::runtime_error naming the endpoint: address in use, device missing, permission.
    ModbusServer(const ModbusEndpoint& endpoint, Tables tables, ModbusTimeouts timeouts, Log log);
    ModbusServer(const ModbusServer&) = delete;
    ModbusServer& operator=(const ModbusServer&) = delete;
    ~ModbusServer();

    int port() const { return port_; }  // the TCP port listened on (useful with port 0)
    // Readable after a client wrote a coil; take_coils_set() then gives each coil a client set
    // to 1 since the last call, in order, and clears them back to 0.
    int written_fd() const override { return written_.fd(); }
    std::vector<int> take_coils_set() override;
    void set_discrete_inputs(int first, const std::vector<bool>& values) override;
    void set_input_registers(int first, std::span<const std::uint16_t> values) override;

  private:
    void serve();
    void serve_rtu();
    int answer(int fd);

    ModbusEndpoint endpoint_;
    Log log_;
    modbus_t* ctx_ = nullptr;
    modbus_mapping_t* map_ = nullptr;
    int listen_fd_ = -1;
    int port_ = 0;
    hal::Notifier stop_;
    hal::Notifier written_;
    mutable std::mutex mutex_;
    std::vector<int> coils_set_;
    std::thread thread_;
};

// The box as a Modbus client (it writes results into a controller's registers): each request
// runs on a thread of its own, its end signalled on completion_fd(); a peer that does not answer
// is an error after the response timeout, never a hang. Connects on each request, so a
// controller restarted between cycles is found again.
class ModbusClient final : public hal::RegisterLink {
  public:
    ModbusClient(const ModbusEndpoint& endpoint, ModbusTimeouts timeouts);
    void start_read_registers(int first_address, int count) override;
    void start_write_registers(int first_address, std::vector<std::uint16_t> values) override;
    void start_write_coil(int address, bool on) override;
    int completion_fd() const override { return request_.fd(); }
    hal::RegisterResult take_result() override;

  private:
    void start(std::function<hal::RegisterResult(modbus_t*)> request);

    ModbusEndpoint endpoint_;
    ModbusTimeouts timeouts_;
    hal::BackgroundJob<hal::RegisterResult>
        request_;  // joined first: a request ends within its timeouts
};

}  // namespace calbox::drivers
