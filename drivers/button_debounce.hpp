#pragma once
// Debounce by stability: a level counts once the line has held it for the window. A bouncing
// contact, a glitch shorter than the window or an edge storm gives no event; each event is
// stamped with the edge that began the stable level, so a press's length is measured from it.
#include <chrono>
#include <optional>

#include "hal/lines.hpp"

namespace calbox::drivers {

class ButtonDebouncer {
  public:
    explicit ButtonDebouncer(std::chrono::nanoseconds window, bool pressed_at_start = false);

    // An edge as the line reports it (pressed: the line's active level). Returns the previous
    // level when that level had already held for the window.
    std::optional<hal::ButtonEvent> edge(bool pressed, std::chrono::nanoseconds at);
    // When settle() must run next, if a level is still waiting to be counted.
    std::optional<std::chrono::nanoseconds> settle_at() const;
    // The line read at `now` (it also catches edges the kernel dropped in a storm).
    std::optional<hal::ButtonEvent> settle(bool pressed_now, std::chrono::nanoseconds now);
    bool pressed() const { return accepted_; }

  private:
    std::chrono::nanoseconds window_;
    bool accepted_;
    bool raw_;
    std::chrono::nanoseconds raw_since_{0};
    bool waiting_ = false;  // raw_ has not been confirmed yet
};

}  // namespace calbox::drivers
