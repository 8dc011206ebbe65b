#pragma once
// A whole press of the box's one button, short or long, told apart by the time between the
// (debounced) press and its release.
#include <chrono>
#include <optional>

#include "hal/lines.hpp"

namespace calbox::firmware {

enum class Press { short_press, long_press };

class PressClassifier {
  public:
    explicit PressClassifier(std::chrono::nanoseconds long_press) : long_press_(long_press) {}
    // A press completes on its release; a release without its press (the box started with the
    // button held) is none.
    std::optional<Press> on_event(const hal::ButtonEvent& event) {
        if (event.pressed) {
            pressed_ = true;
            pressed_at_ = event.at;
            return std::nullopt;
        }
        if (!pressed_) return std::nullopt;
        pressed_ = false;
        const auto held = event.at - pressed_at_;
        return held >= long_press_ ? Press::long_press : Press::short_press;
    }

  private:
    std::chrono::nanoseconds long_press_;
    // Not an optional: GCC 12 warns (maybe-uninitialized) on reading one after inlining.
    bool pressed_ = false;
    std::chrono::nanoseconds pressed_at_{0};
};

}  // namespace calbox::firmware
