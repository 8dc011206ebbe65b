#include <CppUTest/TestHarness.h>
#include <poll.h>
#include <unistd.h>

#include <map>
#include <mutex>
#include <utility>
#include <vector>

#include "drivers/button_debounce.hpp"
#include "drivers/gpio_lines.hpp"
#include "drivers/timerfd_clock.hpp"
#include "firmware/cycle/button_press.hpp"
#include "tests/support/device_errors.hpp"

using namespace calbox;
using namespace std::chrono_literals;
using std::chrono::microseconds;
using std::chrono::nanoseconds;

namespace {

struct RecordedEdge {
    microseconds at;
    bool pressed;
};

struct Outcome {
    std::vector<hal::ButtonEvent> events;
    std::vector<firmware::Press> presses;
};

// Plays a recorded edge sequence through the debouncer, settles it `quiet_after` past the last
// edge (as the driver's timer does) reading the line at the last edge's level, and turns the
// events into presses as the cycle does.
Outcome play(const std::vector<RecordedEdge>& edges, microseconds quiet_after = 100ms) {
    drivers::ButtonDebouncer debouncer(20ms);
    firmware::PressClassifier classifier(1500ms);
    Outcome out;
    auto take = [&](std::optional<hal::ButtonEvent> e) {
        if (!e) return;
        out.events.push_back(*e);
        if (auto p = classifier.on_event(*e)) out.presses.push_back(*p);
    };
    for (const auto& edge : edges) take(debouncer.edge(edge.pressed, edge.at));
    if (!edges.empty()) {
        const auto due = debouncer.settle_at();
        if (due) CHECK(*due <= nanoseconds(edges.back().at + quiet_after));
        take(debouncer.settle(edges.back().pressed, edges.back().at + quiet_after));
    }
    return out;
}

std::vector<RecordedEdge> storm(microseconds from, int edges, microseconds spacing) {
    std::vector<RecordedEdge> out;
    for (int i = 0; i < edges; ++i) out.push_back({from + i * spacing, i % 2 == 0});
    return out;
}

}  // namespace

TEST_GROUP(ButtonDebounce){};

TEST(ButtonDebounce, a_bouncing_short_press_is_one_press_timed_from_its_settled_edges) {
    const auto out = play({{1000us, true},
                           {1200us, false},
                           {1500us, true},
                           {1900us, false},
                           {2300us, true},
                           {301000us, false},
                           {301300us, true},
                           {301700us, false}});
    CHECK_EQUAL(2U, out.events.size());
    CHECK(out.events[0].pressed);
    CHECK(out.events[0].at == nanoseconds(2300us));
    CHECK_FALSE(out.events[1].pressed);
    CHECK(out.events[1].at == nanoseconds(301700us));
    CHECK_EQUAL(1U, out.presses.size());
    CHECK(out.presses[0] == firmware::Press::short_press);
}

TEST(ButtonDebounce, a_held_button_is_a_long_press) {
    const auto out = play({{0us, true}, {400us, false}, {700us, true}, {3'000'000us, false}});
    CHECK_EQUAL(1U, out.presses.size());
    CHECK(out.presses[0] == firmware::Press::long_press);
    CHECK(out.events[0].at == nanoseconds(700us));
}

TEST(ButtonDebounce, a_press_just_under_the_long_press_time_is_short) {
    const auto out = play({{0us, true}, {1'499'000us, false}});
    CHECK_EQUAL(1U, out.presses.size());
    CHECK(out.presses[0] == firmware::Press::short_press);
}

TEST(ButtonDebounce, a_glitch_shorter_than_the_window_is_no_event) {
    const auto out = play({{0us, true}, {5000us, false}});
    CHECK_EQUAL(0U, out.events.size());
}

TEST(ButtonDebounce, an_edge_storm_gives_nothing_until_the_line_holds) {
    // 400 edges 25 us apart, ending where it began: nothing.
    CHECK_EQUAL(0U, play(storm(0us, 400, 25us)).events.size());
    // 401 edges, the line left active and then released 100 ms later: one short press.
    auto edges = storm(0us, 401, 25us);
    edges.push_back({10'000us + 100'000us, false});
    const auto out = play(edges);
    CHECK_EQUAL(2U, out.events.size());
    CHECK(out.events[0].at == nanoseconds(10'000us));
    CHECK_EQUAL(1U, out.presses.size());
}

TEST(ButtonDebounce, a_level_the_kernel_lost_in_a_storm_is_caught_when_settling) {
    drivers::ButtonDebouncer debouncer(20ms);
    CHECK_FALSE(debouncer.edge(false, 0ns).has_value());
    // The last edge seen said released, but the line reads pressed: wait again from now.
    CHECK_FALSE(debouncer.settle(true, 30ms).has_value());
    CHECK(*debouncer.settle_at() == nanoseconds(50ms));
    CHECK_FALSE(debouncer.settle(true, 49ms).has_value());
    const auto event = debouncer.settle(true, 50ms);
    CHECK(event.has_value());
    CHECK(event->pressed);
    CHECK_FALSE(debouncer.settle_at().has_value());
}

TEST(ButtonDebounce, a_release_without_its_press_is_no_press) {
    firmware::PressClassifier classifier(1500ms);
    CHECK_FALSE(classifier.on_event({false, 10ms}).has_value());
}

namespace {

// The kernel stamps edges on CLOCK_MONOTONIC, the clock TimerfdClock reads.
drivers::TimerfdClock monotonic;

nanoseconds now() {
    return monotonic.now();
}

// Stands in for libgpiod: the button's edges arrive through a pipe, outputs are remembered.
struct FakeChipset final : drivers::GpioChipset {
    struct Shared {
        std::map<std::string, bool> outputs;
        std::vector<drivers::GpioEdge> pending;
        bool level = false;
        int pipe_in = -1;
    };
    Shared* shared;
    int pipe_out = -1;
    std::vector<std::string> names;
    explicit FakeChipset(Shared* s) : shared(s) {
        int fds[2];
        if (::pipe(fds) != 0) throw std::runtime_error("pipe");
        pipe_out = fds[0];
        shared->pipe_in = fds[1];
    }
    ~FakeChipset() override {
        ::close(pipe_out);
        ::close(shared->pipe_in);
    }
    int request_edges(const drivers::GpioLineAddress& line, bool, bool,
                      const std::string&) override {
        names.push_back(line.name);
        return static_cast<int>(names.size()) - 1;
    }
    int request_output(const drivers::GpioLineAddress& line, const std::string&) override {
        names.push_back(line.name);
        shared->outputs[line.name] = false;
        return static_cast<int>(names.size()) - 1;
    }
    int event_fd(int) const override { return pipe_out; }
    std::vector<drivers::GpioEdge> read_edges(int) override {
        char drain[64];
        pollfd p{pipe_out, POLLIN, 0};
        while (::poll(&p, 1, 0) > 0 && ::read(pipe_out, drain, sizeof drain) > 0) {
        }
        return std::exchange(shared->pending, {});
    }
    bool value(int) override { return shared->level; }
    void set_value(int handle, bool active) override {
        shared->outputs[names[static_cast<std::size_t>(handle)]] = active;
    }
};

void edge(FakeChipset::Shared& s, bool pressed) {
    s.level = pressed;
    s.pending.push_back({pressed, now()});
    const char byte = 1;
    CHECK_EQUAL(1, ::write(s.pipe_in, &byte, 1));
}

// Waits on the button's descriptor as the event loop does, and reads what it gives.
std::vector<hal::ButtonEvent> wait_for_events(drivers::GpioLines& lines, std::size_t count) {
    std::vector<hal::ButtonEvent> got;
    const auto give_up = now() + 2s;
    while (got.size() < count && now() < give_up) {
        pollfd p{lines.button_fd(), POLLIN, 0};
        if (::poll(&p, 1, 100) <= 0) continue;
        while (auto e = lines.read_button()) got.push_back(*e);
    }
    return got;
}

drivers::GpioLinesSettings fake_settings() {
    drivers::GpioLinesSettings s;
    s.button.name = "BUTTON";
    s.led_busy.name = "LED_BUSY";
    s.light.name = "LIGHT";
    s.debounce = 5ms;
    return s;
}

}  // namespace

TEST_GROUP(GpioLines){};

TEST(GpioLines, edges_wake_the_loop_and_a_level_counts_once_it_has_held) {
    FakeChipset::Shared shared;
    drivers::GpioLines lines(std::make_unique<FakeChipset>(&shared), fake_settings(), monotonic);
    edge(shared, true);
    edge(shared, false);  // a bounce
    edge(shared, true);
    const auto pressed_from = shared.pending.back().at;
    auto got = wait_for_events(lines, 1);
    CHECK_EQUAL(1U, got.size());
    CHECK(got[0].pressed);
    CHECK(got[0].at == pressed_from);
    CHECK(now() - pressed_from >= nanoseconds(5ms));  // not before the window had passed
    edge(shared, false);
    got = wait_for_events(lines, 1);
    CHECK_EQUAL(1U, got.size());
    CHECK_FALSE(got[0].pressed);
    // Quiet afterwards: nothing more to read, the descriptor not readable.
    pollfd p{lines.button_fd(), POLLIN, 0};
    CHECK_EQUAL(0, ::poll(&p, 1, 30));
}

TEST(GpioLines, leds_and_light_reach_their_lines_and_absent_ones_are_skipped) {
    FakeChipset::Shared shared;
    drivers::GpioLines lines(std::make_unique<FakeChipset>(&shared), fake_settings(), monotonic);
    lines.set_led(hal::Led::busy, true);
    lines.set_light(true);
    lines.set_led(hal::Led::error, true);  // not wired on this board
    CHECK(shared.outputs.at("LED_BUSY"));
    CHECK(shared.outputs.at("LIGHT"));
    CHECK_EQUAL(2U, shared.outputs.size());
}

TEST(GpioLines, no_button_configured_is_an_error) {
    FakeChipset::Shared shared;
    auto settings = fake_settings();
    settings.button = {};
    STRCMP_CONTAINS("no button line is configured", test::construction_error([&] {
                                                        drivers::GpioLines(
                                                            std::make_unique<FakeChipset>(&shared),
                                                            settings, monotonic);
                                                    }).c_str());
}

TEST(GpioLines, libgpiod_errors_name_the_line_or_chip) {
    auto chipset = drivers::make_libgpiod_chipset();
    STRCMP_CONTAINS("GPIO chip /dev/gpiochip97 line 3: cannot open the chip: No such file",
                    test::construction_error([&] {
                        chipset->request_edges({"", "/dev/gpiochip97", 3}, true, true, "calbox");
                    }).c_str());
    STRCMP_CONTAINS("GPIO line 'CALBOX_NO_SUCH_LINE': no GPIO chip has a line of that name",
                    test::construction_error([&] {
                        chipset->request_output({"CALBOX_NO_SUCH_LINE", "", -1}, "calbox");
                    }).c_str());
    test::ScratchFile plain("not a chip");
    STRCMP_CONTAINS(("GPIO chip " + plain.path + " line 0: cannot open the chip").c_str(),
                    test::construction_error([&] {
                        chipset->request_output({"", plain.path, 0}, "calbox");
                    }).c_str());
    STRCMP_CONTAINS(
        ("GPIO chip " + plain.path + " line 0: cannot open the chip: Permission denied").c_str(),
        test::error_as_unprivileged_user([&] {
            drivers::make_libgpiod_chipset()->request_output({"", plain.path, 0}, "calbox");
        }).c_str());
}
