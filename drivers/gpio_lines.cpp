#include "drivers/gpio_lines.hpp"

#include <gpiod.h>
#include <poll.h>
#include <sys/epoll.h>
#include <unistd.h>

#include <algorithm>
#include <stdexcept>

#include "drivers/device_error.hpp"

namespace calbox::drivers {

std::string GpioLineAddress::describe() const {
    if (!name.empty()) return "GPIO line '" + name + "'";
    return "GPIO chip " + chip + " line " + std::to_string(offset);
}

namespace {

class Libgpiod final : public GpioChipset {
  public:
    Libgpiod() = default;
    Libgpiod(const Libgpiod&) = delete;
    Libgpiod& operator=(const Libgpiod&) = delete;
    ~Libgpiod() override {
        for (auto& held : held_) {
            gpiod_line_release(held.line);
            gpiod_chip_close(held.chip);
        }
    }

    int request_edges(const GpioLineAddress& address, bool active_low, bool pull_up,
                      const std::string& consumer) override {
        Held held = find(address);
        int flags = 0;
        if (active_low) flags |= GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW;
        if (pull_up) flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP;
        if (gpiod_line_request_both_edges_events_flags(held.line, consumer.c_str(), flags) < 0) {
            const int why = errno;
            gpiod_chip_close(held.chip);
            throw request_error(address, why);
        }
        return keep(held);
    }

    int request_output(const GpioLineAddress& address, const std::string& consumer) override {
        Held held = find(address);
        if (gpiod_line_request_output(held.line, consumer.c_str(), 0) < 0) {
            const int why = errno;
            gpiod_chip_close(held.chip);
            throw request_error(address, why);
        }
        return keep(held);
    }

    int event_fd(int handle) const override { return gpiod_line_event_get_fd(line(handle)); }

    std::vector<GpioEdge> read_edges(int handle) override {
        std::vector<GpioEdge> edges;
        const int fd = event_fd(handle);
        for (;;) {
            pollfd p{fd, POLLIN, 0};
            if (::poll(&p, 1, 0) <= 0 || (p.revents & POLLIN) == 0) break;
            gpiod_line_event events[16];
            const int n = gpiod_line_event_read_fd_multiple(fd, events, 16);
            if (n < 0) throw device_error(what(handle), "reading its events failed");
            for (int i = 0; i < n; ++i) {
                edges.push_back({events[i].event_type == GPIOD_LINE_EVENT_RISING_EDGE,
                                 std::chrono::seconds(events[i].ts.tv_sec) +
                                     std::chrono::nanoseconds(events[i].ts.tv_nsec)});
            }
        }
        return edges;
    }

    bool value(int handle) override {
        const int v = gpiod_line_get_value(line(handle));
        if (v < 0) throw device_error(what(handle), "read failed");
        return v != 0;
    }

    void set_value(int handle, bool active) override {
        if (gpiod_line_set_value(line(handle), active ? 1 : 0) < 0) {
            throw device_error(what(handle), "write failed");
        }
    }

  private:
    struct Held {
        gpiod_chip* chip = nullptr;
        gpiod_line* line = nullptr;
        std::string what;
    };

    static Held find(const GpioLineAddress& address) {
        Held held;
        held.what = address.describe();
        if (!address.name.empty()) {
            errno = 0;
            held.line = gpiod_line_find(address.name.c_str());
            if (held.line == nullptr) {
                if (errno == ENOENT || errno == 0) {
                    throw std::runtime_error(held.what +
                                             ": no GPIO chip has a line of that name (gpioinfo "
                                             "lists them)");
                }
                throw device_error(held.what, "cannot search the GPIO chips");
            }
            held.chip = gpiod_line_get_chip(held.line);
            return held;
        }
        // A path opens as given, so that its own error (permission denied) is the one told;
        // a name, label or number is looked up.
        held.chip = address.chip.find('/') != std::string::npos
                        ? gpiod_chip_open(address.chip.c_str())
                        : gpiod_chip_open_lookup(address.chip.c_str());
        if (held.chip == nullptr) throw device_error(held.what, "cannot open the chip");
        held.line = gpiod_chip_get_line(held.chip, static_cast<unsigned>(address.offset));
        if (address.offset < 0 || held.line == nullptr) {
            const int why = address.offset < 0 ? EINVAL : errno;
            gpiod_chip_close(held.chip);
            throw device_error(held.what, "the chip has no such line", why);
        }
        return held;
    }

    static std::runtime_error request_error(const GpioLineAddress& address, int why) {
        if (why == EBUSY) {
            return std::runtime_error(address.describe() +
                                      ": busy: another program holds it (gpioinfo names it)");
        }
        return device_error(address.describe(), "cannot request it", why);
    }

    int keep(const Held& held) {
        held_.push_back(held);
        return static_cast<int>(held_.size()) - 1;
    }

    gpiod_line* line(int handle) const { return held_.at(static_cast<std::size_t>(handle)).line; }
    const std::string& what(int handle) const {
        return held_.at(static_cast<std::size_t>(handle)).what;
    }

    std::vector<Held> held_;
};

}  // namespace

std::unique_ptr<GpioChipset> make_libgpiod_chipset() {
    return std::make_unique<Libgpiod>();
}

GpioLines::GpioLines(std::unique_ptr<GpioChipset> chipset, GpioLinesSettings settings,
                     hal::Clock& clock)
    : chipset_(std::move(chipset)),
      settings_(std::move(settings)),
      debouncer_(settings_.debounce),
      clock_(clock),
      settle_timer_(clock.make_timer()) {
    if (!chipset_) throw std::invalid_argument("GpioLines: no chipset");
    if (settings_.button.empty()) throw std::runtime_error("gpio: no button line is configured");
    button_ = chipset_->request_edges(settings_.button, settings_.button_active_low,
                                      settings_.button_pull_up, settings_.consumer);
    debouncer_ = ButtonDebouncer(settings_.debounce, chipset_->value(button_));
    const std::array<const GpioLineAddress*, 3> leds{&settings_.led_ready, &settings_.led_busy,
                                                     &settings_.led_error};
    for (std::size_t i = 0; i < leds.size(); ++i) {
        if (!leds[i]->empty()) leds_[i] = chipset_->request_output(*leds[i], settings_.consumer);
    }
    if (!settings_.light.empty())
        light_ = chipset_->request_output(settings_.light, settings_.consumer);

    epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
    if (epoll_fd_ < 0) throw device_error("gpio", "cannot create the button's epoll set");
    for (const int fd : {chipset_->event_fd(button_), settle_timer_->fd()}) {
        epoll_event e{};
        e.events = EPOLLIN;
        e.data.fd = fd;
        if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &e) < 0) {
            const int why = errno;
            ::close(epoll_fd_);
            throw device_error(settings_.button.describe(), "cannot watch its events", why);
        }
    }
}

GpioLines::~GpioLines() {
    ::close(epoll_fd_);
}

std::optional<hal::ButtonEvent> GpioLines::read_button() {
    if (counted_.empty()) {
        for (const GpioEdge& edge : chipset_->read_edges(button_)) {
            if (auto event = debouncer_.edge(edge.active, edge.at)) counted_.push_back(*event);
        }
        settle_timer_->take_expirations();
        const auto now = clock_.now();
        if (const auto due = debouncer_.settle_at(); due && now >= *due) {
            if (auto event = debouncer_.settle(chipset_->value(button_), now)) {
                counted_.push_back(*event);
            }
        }
        arm_settle_timer();
    }
    if (counted_.empty()) return std::nullopt;
    const hal::ButtonEvent event = counted_.front();
    counted_.pop_front();
    return event;
}

void GpioLines::arm_settle_timer() {
    const auto due = debouncer_.settle_at();
    if (!due) {
        settle_timer_->disarm();
        return;
    }
    // A time already past fires at once: the timer takes only positive delays.
    settle_timer_->arm(std::max(*due - clock_.now(), std::chrono::nanoseconds(1)),
                       std::chrono::nanoseconds(0));
}

void GpioLines::set_led(hal::Led which, bool on) {
    const int handle = leds_[static_cast<std::size_t>(which)];
    if (handle >= 0) chipset_->set_value(handle, on);
}

void GpioLines::set_light(bool on) {
    if (light_ >= 0) chipset_->set_value(light_, on);
}

}  // namespace calbox::drivers
