#include "drivers/button_debounce.hpp"

#include <stdexcept>

namespace calbox::drivers {

ButtonDebouncer::ButtonDebouncer(std::chrono::nanoseconds window, bool pressed_at_start)
    : window_(window), accepted_(pressed_at_start), raw_(pressed_at_start) {
    if (window < std::chrono::nanoseconds(0)) {
        throw std::invalid_argument("debounce window must not be negative");
    }
}

std::optional<hal::ButtonEvent> ButtonDebouncer::edge(bool pressed, std::chrono::nanoseconds at) {
    std::optional<hal::ButtonEvent> counted;
    if (waiting_ && at - raw_since_ >= window_ && raw_ != accepted_) {
        accepted_ = raw_;
        counted = hal::ButtonEvent{accepted_, raw_since_};
    }
    raw_since_ = at;  // any edge means the line moved, even one whose opposite was lost
    raw_ = pressed;
    waiting_ = true;
    return counted;
}

std::optional<std::chrono::nanoseconds> ButtonDebouncer::settle_at() const {
    if (!waiting_) return std::nullopt;
    return raw_since_ + window_;
}

std::optional<hal::ButtonEvent> ButtonDebouncer::settle(bool pressed_now,
                                                        std::chrono::nanoseconds now) {
    if (pressed_now != raw_) {  // an edge was lost: the level read now starts again
        raw_ = pressed_now;
        raw_since_ = now;
        waiting_ = true;
        return std::nullopt;
    }
    if (!waiting_ || now - raw_since_ < window_) return std::nullopt;
    waiting_ = false;
    if (raw_ == accepted_) return std::nullopt;
    accepted_ = raw_;
    return hal::ButtonEvent{accepted_, raw_since_};
}

}  // namespace calbox::drivers
