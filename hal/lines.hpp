#pragma once
// What the firmware needs of GPIO: one button, status LEDs and the artifact light.
#include <chrono>
#include <optional>

namespace calbox::hal {

enum class Led { ready, busy, error };

struct ButtonEvent {
    bool pressed = false;
    std::chrono::nanoseconds at{0};  // monotonic time of the edge
};

class Lines {
  public:
    virtual ~Lines() = default;
    virtual int button_fd() const = 0;                     // readable when an edge arrived
    virtual std::optional<ButtonEvent> read_button() = 0;  // debounced; empty when none is pending
    virtual void set_led(Led which, bool on) = 0;
    virtual void set_light(bool on) = 0;
};

}  // namespace calbox::hal
