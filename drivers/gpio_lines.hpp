#pragma once
// The box's button, status LEDs and artifact light on GPIO lines (libgpiod 1.6, the v1 API).
#include <array>
#include <chrono>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "drivers/button_debounce.hpp"
#include "hal/clock.hpp"
#include "hal/lines.hpp"

namespace calbox::drivers {

// A line by its name (preferred: it survives a kernel that numbers chips differently) or by
// chip (name, path or number) and offset.
struct GpioLineAddress {
    std::string name;
    std::string chip;
    int offset = -1;
    bool empty() const { return name.empty() && chip.empty(); }
    std::string describe() const;  // for messages: "line 'BUTTON'" or "gpiochip0 line 17"
};

struct GpioLinesSettings {
    GpioLineAddress button;
    bool button_active_low = true;  // a button to ground with the pull-up on
    bool button_pull_up = true;
    std::chrono::milliseconds debounce{20};
    GpioLineAddress led_ready, led_busy, led_error, light;  // each optional
    std::string consumer = "calbox";
};

struct GpioEdge {
    bool active = false;  // the line's active level after the edge (active-low applied)
    std::chrono::nanoseconds at{0};
};

// The seam over libgpiod: the lines requested, their events and values. Every call throws
// std::runtime_error naming the line: no such chip or line, line busy, permission denied.
class GpioChipset {
  public:
    virtual ~GpioChipset() = default;
    virtual int request_edges(const GpioLineAddress& line, bool active_low, bool pull_up,
                              const std::string& consumer) = 0;  // returns a handle
    virtual int request_output(const GpioLineAddress& line, const std::string& consumer) = 0;
    virtual int event_fd(int handle) const = 0;
    virtual std::vector<GpioEdge> read_edges(int handle) = 0;  // those pending, never blocks
    virtual bool value(int handle) = 0;
    virtual void set_value(int handle, bool active) = 0;
};

std::unique_ptr<GpioChipset> make_libgpiod_chipset();

class GpioLines final : public hal::Lines {
  public:
    // `clock` must be CLOCK_MONOTONIC's (TimerfdClock), the clock the kernel stamps edges with.
    GpioLines(std::unique_ptr<GpioChipset> chipset, GpioLinesSettings settings, hal::Clock& clock);
    GpioLines(const GpioLines&) = delete;
    GpioLines& operator=(const GpioLines&) = delete;
    ~GpioLines() override;
    // Readable when an edge arrived or a level has held long enough to count.
    int button_fd() const override { return epoll_fd_; }
    std::optional<hal::ButtonEvent> read_button() override;
    void set_led(hal::Led which, bool on) override;
    void set_light(bool on) override;

  private:
    void arm_settle_timer();

    std::unique_ptr<GpioChipset> chipset_;
    GpioLinesSettings settings_;
    int button_ = -1;
    std::array<int, 3> leds_{-1, -1, -1};
    int light_ = -1;
    ButtonDebouncer debouncer_;
    std::deque<hal::ButtonEvent> counted_;
    hal::Clock& clock_;
    std::unique_ptr<hal::Timer> settle_timer_;
    int epoll_fd_ = -1;
};

}  // namespace calbox::drivers
