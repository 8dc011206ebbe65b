#pragma once
// CppUTest mocks of the hal/ interfaces the firmware's tests drive by expectation: the machine's
// serial port (mock("serial")) and a controller's registers (mock("registers")). The other
// devices are the sim board's (board/sim) or the tests' own fakes (tests/support).
#include <CppUTest/TestHarness.h>
#include <CppUTestExt/MockSupport.h>

#include <algorithm>
#include <deque>
#include <map>
#include <memory>

#include "hal/register_link.hpp"
#include "hal/serial_port.hpp"

namespace calbox::mocks {

class MockSerialPort final : public hal::SerialPort {
  public:
    std::string incoming;  // bytes the far end has sent
    std::string written;   // bytes written to the far end
    int fd() const override { return mock("serial").actualCall("fd").returnIntValueOrDefault(-1); }
    std::size_t read_some(std::span<std::uint8_t> into) override {
        const std::size_t n = std::min(into.size(), incoming.size());
        std::copy_n(incoming.begin(), n, into.begin());
        incoming.erase(0, n);
        return n;
    }
    std::size_t write_some(std::span<const std::uint8_t> bytes) override {
        const auto limit = static_cast<std::size_t>(
            mock("serial")
                .actualCall("write_some")
                .returnUnsignedIntValueOrDefault(static_cast<unsigned>(bytes.size())));
        const std::size_t n = std::min(limit, bytes.size());
        written.append(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
        return n;
    }
};

class MockRegisterLink final : public hal::RegisterLink {
  public:
    std::deque<hal::RegisterResult> results;
    void start_read_registers(int first, int count) override {
        mock("registers")
            .actualCall("start_read_registers")
            .withIntParameter("first", first)
            .withIntParameter("count", count);
    }
    std::vector<std::pair<int, std::vector<std::uint16_t>>> written;  // every write's words
    void start_write_registers(int first, std::vector<std::uint16_t> values) override {
        written.emplace_back(first, values);
        mock("registers")
            .actualCall("start_write_registers")
            .withIntParameter("first", first)
            .withUnsignedIntParameter("count", static_cast<unsigned>(values.size()));
    }
    void start_write_coil(int address, bool on) override {
        mock("registers")
            .actualCall("start_write_coil")
            .withIntParameter("address", address)
            .withBoolParameter("on", on);
    }
    int completion_fd() const override {
        return mock("registers").actualCall("completion_fd").returnIntValueOrDefault(-1);
    }
    hal::RegisterResult take_result() override {
        mock("registers").actualCall("take_result");
        if (results.empty()) FAIL("MockRegisterLink: take_result() with no result queued");
        auto r = std::move(results.front());
        results.pop_front();
        return r;
    }
};

}  // namespace calbox::mocks
