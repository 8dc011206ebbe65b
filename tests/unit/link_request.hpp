#pragma once
// A machine link's request run to its end on the event loop (the link tests' one way).
#include <CppUTest/TestHarness.h>

#include <chrono>
#include <optional>
#include <utility>

#include "firmware/links/machine_link.hpp"
#include "firmware/loop/event_loop.hpp"

template <class Start>
calbox::firmware::JobOutcome run_to_its_end(calbox::firmware::EventLoop& loop,
                                            Start start_request) {
    using namespace std::chrono_literals;
    std::optional<calbox::firmware::JobOutcome> outcome;
    start_request([&outcome](calbox::firmware::JobOutcome o) { outcome = std::move(o); });
    const auto deadline = std::chrono::steady_clock::now() + 60s;
    while (!outcome && std::chrono::steady_clock::now() < deadline) loop.run_once(50ms);
    CHECK_TEXT(outcome.has_value(), "the request never ended");
    return *outcome;
}
