// The G-code host protocol against a scripted printer: exact bytes on the wire (line numbers and
// checksums worked by hand), resends, busy, fatal errors, the start-up banner, actions, timeouts.
#include <CppUTest/TestHarness.h>
#include <CppUTestExt/MockSupport.h>

#include <optional>

#include "firmware/links/gcode_host.hpp"
#include "tests/mocks/hal_mocks.hpp"
#include "tests/support/fake_clock.hpp"

using namespace calbox;
using namespace std::chrono_literals;

TEST_GROUP(GcodeHost) {
    mocks::MockSerialPort port;
    test::FakeClock clock;
    std::vector<std::string> log;
    std::optional<firmware::JobOutcome> outcome;
    std::unique_ptr<firmware::GcodeHost> host;

    void setup() override {
        mock().ignoreOtherCalls();
        host = std::make_unique<firmware::GcodeHost>(
            port, clock, firmware::GcodeHostSettings{1, 1000ms, 3, 0ms},
            [this](const std::string& l) { log.push_back(l); });
    }
    void teardown() override {
        host.reset();
        mock().clear();
    }
    void start(const std::vector<std::string>& lines) {
        host->start_job(lines, [this](firmware::JobOutcome o) { outcome = std::move(o); });
    }
    void printer_says(const std::string& text) {
        port.incoming += text;
        host->on_readable();
    }
};

TEST(GcodeHost, numbers_and_checksums_each_line_and_sends_one_per_ok) {
    start({"G28", "; a comment line", "G1 X1 Y2 ; move", "   ", "M503"});
    STRCMP_EQUAL("N0 M110 N0*125\n", port.written.c_str());
    printer_says("ok\n");
    STRCMP_EQUAL("N0 M110 N0*125\nN1 G28*18\n", port.written.c_str());
    printer_says("ok\nok\n");  // the second ok arrives only after N2 was sent
    printer_says("echo:  M665 L250.000\nok\n");
    STRCMP_EQUAL("N0 M110 N0*125\nN1 G28*18\nN2 G1 X1 Y2*40\nN3 M503*38\n", port.written.c_str());
    CHECK(outcome.has_value());
    CHECK(outcome->ok);
    CHECK_EQUAL(1u, outcome->replies.size());
    STRCMP_EQUAL("echo:  M665 L250.000", outcome->replies[0].c_str());
    CHECK_EQUAL(4u, host->transcript().size());
}

TEST(GcodeHost, resends_from_the_line_the_printer_asks_for) {
    start({"G28", "G1 X1 Y2"});
    printer_says("ok\nok\n");
    printer_says("Error:checksum mismatch, Last Line: 1\nResend: 2\nok\n");
    printer_says("ok\n");
    STRCMP_EQUAL("N0 M110 N0*125\nN1 G28*18\nN2 G1 X1 Y2*40\nN2 G1 X1 Y2*40\n",
                 port.written.c_str());
    CHECK(outcome && outcome->ok);
}

TEST(GcodeHost, a_resend_storm_ends_the_job) {
    start({"G28", "G1 X1 Y2"});
    printer_says("ok\nok\n");
    for (int i = 0; i < 4; ++i) printer_says("Error:checksum mismatch, Last Line: 1\nrs N2\nok\n");
    CHECK(outcome && !outcome->ok);
    STRCMP_CONTAINS("too noisy", outcome->error.c_str());
    const auto sent = port.written.size();
    printer_says("ok\n");
    CHECK_EQUAL(sent, port.written.size());  // nothing more goes out
}

TEST(GcodeHost, busy_keeps_a_slow_printer_alive_and_silence_ends_the_job) {
    start({"G28"});
    printer_says("ok\n");
    clock.advance(900ms);
    printer_says("echo:busy: processing\n");
    clock.advance(900ms);
    host->on_timer();
    CHECK_FALSE(outcome.has_value());
    clock.advance(200ms);
    host->on_timer();
    CHECK(outcome && !outcome->ok);
    STRCMP_EQUAL("the printer did not answer within 1 s (line 1: G28)", outcome->error.c_str());
}

TEST(GcodeHost, an_error_that_is_not_about_transport_ends_the_job) {
    start({"G28", "G1 X1 Y2"});
    printer_says("ok\nError:Printer halted. kill() called!\n");
    CHECK(outcome && !outcome->ok);
    STRCMP_EQUAL("the printer reported \"Error:Printer halted. kill() called!\"",
                 outcome->error.c_str());
    const auto sent = port.written.size();
    printer_says("ok\n");
    CHECK_EQUAL(sent, port.written.size());
}

TEST(GcodeHost, a_reset_mid_job_abandons_it) {
    start({"G28", "G1 X1 Y2"});
    printer_says("ok\nstart\necho:Marlin 2.1.2\n");
    CHECK(outcome && !outcome->ok);
    STRCMP_CONTAINS("restarted mid-job", outcome->error.c_str());
}

TEST(GcodeHost, action_lines_pause_resume_and_cancel) {
    start({"G28", "G1 X1 Y2"});
    printer_says("//action:pause\nok\n");
    STRCMP_EQUAL("N0 M110 N0*125\n", port.written.c_str());  // paused: nothing sent on the ok
    printer_says("//action:resume\n");
    STRCMP_EQUAL("N0 M110 N0*125\nN1 G28*18\n", port.written.c_str());
    printer_says("//action:cancel\n");
    CHECK(outcome && !outcome->ok);
    STRCMP_CONTAINS("cancelled the job", outcome->error.c_str());
}

TEST(GcodeHost, a_window_of_two_keeps_two_lines_in_flight) {
    host = std::make_unique<firmware::GcodeHost>(
        port, clock, firmware::GcodeHostSettings{2, 1000ms, 3, 0ms}, [](const std::string&) {});
    start({"G28", "G1 X1 Y2"});
    STRCMP_EQUAL("N0 M110 N0*125\nN1 G28*18\n", port.written.c_str());
    printer_says("ok\nok\nok\n");
    CHECK(outcome && outcome->ok);
}

// A board that resets when the port opens boots for a while and prints "start": the first job
// waits for that banner (or, from a board that does not reset, for the wait to pass) before it
// sends anything, so that no line is lost in the boot loader.
TEST(GcodeHost, the_first_job_waits_for_the_start_up_banner) {
    host = std::make_unique<firmware::GcodeHost>(
        port, clock, firmware::GcodeHostSettings{1, 1000ms, 3, 2000ms}, [](const std::string&) {});
    start({"M503"});
    STRCMP_EQUAL("", port.written.c_str());
    printer_says("start\necho:Marlin 2.1.2\n");
    STRCMP_EQUAL("N0 M110 N0*125\n", port.written.c_str());
    printer_says("ok\nok\n");
    CHECK(outcome && outcome->ok);
}

// grbl reads plain lines: no number, no checksum, no M110; each answered by ok or error:N, an
// error or an alarm ends the job naming the line and what grbl means by it.
TEST(GcodeHost, grbl_gets_plain_lines_and_its_errors_end_the_job) {
    firmware::GcodeHostSettings grbl;
    grbl.startup_wait = 0ms;
    grbl.numbered_lines = false;
    host = std::make_unique<firmware::GcodeHost>(port, clock, grbl, [](const std::string&) {});
    start({"G21 ; mm", "G0 X1 Y2", "M3 S500"});
    STRCMP_EQUAL("G21\n", port.written.c_str());
    printer_says("ok\n");
    STRCMP_EQUAL("G21\nG0 X1 Y2\n", port.written.c_str());
    printer_says("error:20\n");
    CHECK(outcome && !outcome->ok);
    STRCMP_EQUAL(
        "the machine answered \"error:20\" (grbl: an unsupported or invalid command) to line 2: "
        "G0 X1 Y2",
        outcome->error.c_str());
    const auto sent = port.written.size();
    printer_says("ok\n");
    CHECK_EQUAL(sent, port.written.size());  // nothing more went
    outcome.reset();
    start({"G0 X900 Y0"});
    printer_says("ALARM:2\n");
    CHECK(outcome && !outcome->ok);
    STRCMP_CONTAINS("ALARM:2\" (grbl: a move beyond the machine's travel (soft limit)) to line 1",
                    outcome->error.c_str());
}

// grbl's welcome line is its start-up banner: the first job waits for it, and one mid-job is a
// reset that abandons the job.
TEST(GcodeHost, grbls_welcome_is_its_start_up_banner) {
    firmware::GcodeHostSettings grbl;
    grbl.startup_wait = 2000ms;
    grbl.numbered_lines = false;
    host = std::make_unique<firmware::GcodeHost>(port, clock, grbl, [](const std::string&) {});
    start({"G21", "G0 X1"});
    STRCMP_EQUAL("", port.written.c_str());
    printer_says("\r\nGrbl 1.1h ['$' for help]\r\n");
    STRCMP_EQUAL("G21\n", port.written.c_str());
    printer_says("ok\nGrbl 1.1h ['$' for help]\n");
    CHECK(outcome && !outcome->ok);
    STRCMP_CONTAINS("restarted mid-job", outcome->error.c_str());
}

TEST(GcodeHost, a_printer_that_stays_silent_at_start_is_sent_to_after_the_wait) {
    host = std::make_unique<firmware::GcodeHost>(
        port, clock, firmware::GcodeHostSettings{1, 1000ms, 3, 2000ms}, [](const std::string&) {});
    start({"M503"});
    clock.advance(1900ms);
    host->on_timer();
    STRCMP_EQUAL("", port.written.c_str());
    clock.advance(100ms);
    host->on_timer();
    STRCMP_EQUAL("N0 M110 N0*125\n", port.written.c_str());
    printer_says("ok\nok\n");
    CHECK(outcome && outcome->ok);
    // The next job does not wait again.
    outcome.reset();
    start({"M503"});
    STRCMP_EQUAL("N0 M110 N0*125\nN1 M503*36\nN0 M110 N0*125\n", port.written.c_str());
}

TEST(GcodeHost, the_transcript_keeps_only_the_last_lines_it_is_allowed) {
    firmware::GcodeHostSettings settings{1, 1000ms, 3, 0ms};
    settings.transcript_lines = 2;
    host = std::make_unique<firmware::GcodeHost>(port, clock, settings, [](const std::string&) {});
    start({"G28", "M503"});
    printer_says("ok\nok\nok\n");
    CHECK(outcome && outcome->ok);
    CHECK_EQUAL(2u, host->transcript().size());
    STRCMP_EQUAL("N1 G28*18", host->transcript().front().c_str());
    STRCMP_EQUAL("N2 M503*39", host->transcript().back().c_str());
}
