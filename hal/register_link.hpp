#pragma once
// Modbus-style registers and coils, asynchronous: a request starts, its completion is
// signalled on a file descriptor, then its result is taken.
#include <cstdint>
#include <string>
#include <vector>

namespace calbox::hal {

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

}  // namespace calbox::hal
