#pragma once
// Modbus-style registers and coils, asynchronous: a request starts, its completion is
// signalled on a file descriptor, then its result is taken.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace calbox::hal {

// How long a Modbus peer has, whichever its role.
struct ModbusTimeouts {
    std::uint32_t response_ms = 1000;  // the whole reply (client) or a frame once begun (both)
    std::uint32_t byte_ms = 500;       // between two bytes of one frame
};

struct RegisterResult {
    std::vector<std::uint16_t> values;  // for reads
    std::string error;                  // empty on success
    bool ok() const { return error.empty(); }
};

class RegisterLink {
  public:
    virtual ~RegisterLink() = default;
    // Each start_* throws std::logic_error while another request is in flight.
    virtual void start_read_registers(int first_address, int count) = 0;
    virtual void start_write_registers(int first_address, std::vector<std::uint16_t> values) = 0;
    virtual void start_write_coil(int address, bool on) = 0;
    virtual int completion_fd() const = 0;
    virtual RegisterResult take_result() = 0;
};

// The box's own registers and coils, as a controller (a PLC) reads and writes them: the box sets
// its status inputs and registers; a coil the controller set is told on written_fd().
class RegisterServer {
  public:
    virtual ~RegisterServer() = default;
    // Readable after a client wrote a coil; take_coils_set() then gives each coil a client set
    // to 1 since the last call, in order, and clears them back to 0.
    virtual int written_fd() const = 0;
    virtual std::vector<int> take_coils_set() = 0;
    virtual void set_discrete_inputs(int first, const std::vector<bool>& values) = 0;
    virtual void set_input_registers(int first, std::span<const std::uint16_t> values) = 0;
};

}  // namespace calbox::hal
