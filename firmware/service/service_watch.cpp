#include "firmware/service/service_watch.hpp"

#include <chrono>

#include "core/number_text.hpp"

namespace calbox::firmware {

std::string service_status(const Cycle& cycle) {
    const CycleState state = cycle.state();
    const int number = cycle.report().number;
    if (state == CycleState::error)
        return "cycle " + std::to_string(number) + ": error: " + cycle.error();
    const int completed = cycle.cycles_completed();
    std::string line = state == CycleState::idle
                           ? "idle, " + std::to_string(completed) +
                                 (completed == 1 ? " cycle completed" : " cycles completed")
                           : "cycle " + std::to_string(number) + ": " + state_name(state);
    if (cycle.prompt() != Prompt::none)
        line += std::string(": waiting: ") + prompt_text(cycle.prompt());
    return line;
}

ServiceWatch::ServiceWatch(EventLoop& loop, hal::Clock& clock, Cycle& cycle,
                           hal::Supervisor& supervisor, const hal::Log& log)
    : loop_(loop),
      cycle_(cycle),
      supervisor_(supervisor),
      ready_timer_(clock.make_timer()),
      alive_timer_(clock.make_timer()) {
    // Ready on the loop's first turn: every part is up by then, and the loop turns.
    loop_.watch(ready_timer_->fd(), [this] {
        ready_timer_->take_expirations();
        loop_.unwatch(ready_timer_->fd());
        supervisor_.ready();
        tell_status();
    });
    ready_timer_->arm(std::chrono::nanoseconds(1), std::chrono::nanoseconds(0));
    if (const auto timeout = supervisor_.watchdog_timeout()) {
        // Four pets a timeout: a handler that takes a while (a frame merged, a file written) is
        // not mistaken for a hung loop, which stops petting for good.
        const auto every = std::chrono::duration_cast<std::chrono::nanoseconds>(*timeout) / 4;
        loop_.watch(alive_timer_->fd(), [this] {
            alive_timer_->take_expirations();
            supervisor_.alive();
        });
        alive_timer_->arm(every, every);
        log("service: the watchdog petted every " +
            number_text("%.2f s", std::chrono::duration<double>(every).count()) + " (timeout " +
            number_text("%.1f s)", std::chrono::duration<double>(*timeout).count()));
    }
    news_ = cycle_.subscribe({[this](Prompt, int) { tell_status(); },
                              [this](CycleState) { tell_status(); },
                              {},
                              {},
                              {}});
}

ServiceWatch::~ServiceWatch() {
    loop_.unwatch(ready_timer_->fd());
    loop_.unwatch(alive_timer_->fd());
    supervisor_.stopping();
}

void ServiceWatch::tell_status() {
    const std::string status = service_status(cycle_);
    if (status == told_status_) return;
    told_status_ = status;
    supervisor_.status(status);
}

}  // namespace calbox::firmware
