// The mocks stand in for devices in firmware tests; these pin down that they honour the
// contracts of hal/ and that CppUTest's expectations see every call.
#include "tests/mocks/hal_mocks.hpp"

using namespace calbox;

TEST_GROUP(HalMocks){void teardown() override{mock().checkExpectations();
mock().clear();
}
}
;

TEST(HalMocks, camera_hands_out_queued_captures_in_order) {
    mocks::MockCamera camera;
    hal::CaptureResult first;
    first.frames.resize(2);
    camera.results.push_back(first);
    camera.results.push_back(hal::CaptureResult{{}, "sensor timeout"});
    mock("camera").expectOneCall("start_capture").withIntParameter("frame_count", 2);
    mock("camera").expectNCalls(2, "take_frames");
    camera.start_capture(hal::CaptureRequest{2, {}, {}});
    CHECK_EQUAL(2u, camera.take_frames().frames.size());
    const auto failed = camera.take_frames();
    CHECK_FALSE(failed.ok());
    STRCMP_EQUAL("sensor timeout", failed.error.c_str());
}

TEST(HalMocks, lines_record_leds_and_deliver_button_edges) {
    mocks::MockLines lines;
    lines.button_events.push_back({true, std::chrono::milliseconds(5)});
    mock("lines")
        .expectOneCall("set_led")
        .withIntParameter("which", static_cast<int>(hal::Led::busy))
        .withBoolParameter("on", true);
    mock("lines").expectOneCall("set_light").withBoolParameter("on", false);
    mock("lines").expectNCalls(2, "read_button");
    lines.set_led(hal::Led::busy, true);
    lines.set_light(false);
    const auto e = lines.read_button();
    CHECK(e.has_value());
    CHECK(e->pressed);
    CHECK_FALSE(lines.read_button().has_value());
}

TEST(HalMocks, serial_port_accepts_partial_writes) {
    mocks::MockSerialPort port;
    port.incoming = "ok\n";
    mock("serial").expectOneCall("write_some").andReturnValue(3u);
    const std::string line = "G28 X\n";
    const auto n =
        port.write_some(std::span(reinterpret_cast<const std::uint8_t*>(line.data()), line.size()));
    CHECK_EQUAL(3u, n);
    STRCMP_EQUAL("G28", port.written.c_str());
    std::uint8_t buffer[8];
    CHECK_EQUAL(3u, port.read_some(buffer));
    CHECK_EQUAL(0u, port.read_some(buffer));
}

TEST(HalMocks, register_link_reports_results) {
    mocks::MockRegisterLink link;
    link.results.push_back(hal::RegisterResult{{1, 2, 3}, ""});
    mock("registers")
        .expectOneCall("start_read_registers")
        .withIntParameter("first", 100)
        .withIntParameter("count", 3);
    mock("registers").expectOneCall("take_result");
    link.start_read_registers(100, 3);
    CHECK_EQUAL(3u, link.take_result().values.size());
}

TEST(HalMocks, display_refuses_a_frame_of_the_wrong_size) {
    mocks::MockDisplay display;
    mock("display").expectNCalls(2, "show");
    hal::MonoBitmap frame;
    frame.set(3, 4, true);
    frame.set(500, 4, true);  // clipped
    display.show(frame);
    CHECK(display.frames.back().at(3, 4));
    CHECK_FALSE(display.frames.back().at(4, 4));
    CHECK_THROWS(std::invalid_argument, display.show(hal::MonoBitmap(64, 32)));
}

TEST(HalMocks, clock_timers_and_storage_record_calls) {
    mocks::MockClock clock;
    mock("clock").expectOneCall("make_timer");
    mock("clock")
        .expectOneCall("arm")
        .withLongIntParameter("after_ns", 1000)
        .withLongIntParameter("period_ns", 0);
    auto timer = clock.make_timer();
    timer->arm(std::chrono::microseconds(1), std::chrono::nanoseconds(0));
    mocks::MockStorage storage;
    mock("storage").expectOneCall("replace_file").withStringParameter("name", "config.toml");
    mock("storage").expectOneCall("read_file").withStringParameter("name", "config.toml");
    mock("storage").expectOneCall("read_file").withStringParameter("name", "missing");
    storage.replace_file("config.toml", "x = 1\n");
    STRCMP_EQUAL("x = 1\n", storage.read_file("config.toml")->c_str());
    CHECK_FALSE(storage.read_file("missing").has_value());
}
