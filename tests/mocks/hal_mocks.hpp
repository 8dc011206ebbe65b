#pragma once
// CppUTest mocks of every hal/ interface. Expectations are set with mock("name") per device:
// mock("camera"), mock("lines"), mock("serial"), mock("registers"), mock("display"),
// mock("clock"), mock("storage").
#include <CppUTest/TestHarness.h>
#include <CppUTestExt/MockSupport.h>

#include <algorithm>
#include <deque>
#include <map>
#include <memory>

#include "hal/camera.hpp"
#include "hal/clock.hpp"
#include "hal/display.hpp"
#include "hal/lines.hpp"
#include "hal/register_link.hpp"
#include "hal/serial_port.hpp"
#include "hal/storage.hpp"

namespace calbox::mocks {

class MockCamera final : public hal::Camera {
  public:
    std::deque<hal::CaptureResult> results;  // what take_frames() hands out, in order
    void start_capture(const hal::CaptureRequest& r) override {
        mock("camera").actualCall("start_capture").withIntParameter("frame_count", r.frame_count);
    }
    int completion_fd() const override {
        return mock("camera").actualCall("completion_fd").returnIntValueOrDefault(-1);
    }
    hal::CaptureResult take_frames() override {
        mock("camera").actualCall("take_frames");
        if (results.empty()) FAIL("MockCamera: take_frames() with no result queued");
        auto r = std::move(results.front());
        results.pop_front();
        return r;
    }
};

class MockLines final : public hal::Lines {
  public:
    std::deque<hal::ButtonEvent> button_events;
    int button_fd() const override {
        return mock("lines").actualCall("button_fd").returnIntValueOrDefault(-1);
    }
    std::optional<hal::ButtonEvent> read_button() override {
        mock("lines").actualCall("read_button");
        if (button_events.empty()) return std::nullopt;
        auto e = button_events.front();
        button_events.pop_front();
        return e;
    }
    void set_led(hal::Led which, bool on) override {
        mock("lines")
            .actualCall("set_led")
            .withIntParameter("which", static_cast<int>(which))
            .withBoolParameter("on", on);
    }
    void set_light(bool on) override {
        mock("lines").actualCall("set_light").withBoolParameter("on", on);
    }
};

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

class MockDisplay final : public hal::Display {
  public:
    std::vector<hal::MonoBitmap> frames;  // every frame shown
    int width_px() const override { return 128; }
    int height_px() const override { return 64; }
    void show(const hal::MonoBitmap& frame) override {
        mock("display").actualCall("show");
        if (frame.width_px() != width_px() || frame.height_px() != height_px()) {
            throw std::invalid_argument("frame size does not match the display");
        }
        frames.push_back(frame);
    }
};

class MockTimer final : public hal::Timer {
  public:
    int fd() const override { return -1; }
    void arm(std::chrono::nanoseconds after, std::chrono::nanoseconds period) override {
        mock("clock")
            .actualCall("arm")
            .withLongIntParameter("after_ns", static_cast<long>(after.count()))
            .withLongIntParameter("period_ns", static_cast<long>(period.count()));
    }
    void disarm() override { mock("clock").actualCall("disarm"); }
    std::uint64_t take_expirations() override {
        return mock("clock").actualCall("take_expirations").returnUnsignedLongIntValueOrDefault(0);
    }
};

class MockClock final : public hal::Clock {
  public:
    std::chrono::nanoseconds time{0};  // set by the test
    std::chrono::nanoseconds now() const override { return time; }
    std::unique_ptr<hal::Timer> make_timer() override {
        mock("clock").actualCall("make_timer");
        return std::make_unique<MockTimer>();
    }
};

class MockStorage final : public hal::Storage {
  public:
    std::map<std::string, std::string> files;
    std::optional<std::string> read_file(const std::string& name) override {
        mock("storage").actualCall("read_file").withStringParameter("name", name.c_str());
        const auto it = files.find(name);
        if (it == files.end()) return std::nullopt;
        return it->second;
    }
    void replace_file(const std::string& name, const std::string& contents) override {
        mock("storage").actualCall("replace_file").withStringParameter("name", name.c_str());
        files[name] = contents;
    }
    std::vector<Entry> list_files() override {
        std::vector<Entry> out;
        for (const auto& [name, contents] : files) out.push_back({name, contents.size()});
        return out;
    }
    void remove_file(const std::string& name) override { files.erase(name); }
};

}  // namespace calbox::mocks
