// LinuxCNC through linuxcncrsh: the link against the twin's linuxcncrsh on loopback (the G54 zero
// set by MDI and read back, a job run line by line, each refusal in one line naming it), the
// work zero's words for each controller, and — in the group LinuxCncReal, which
// tests/network/linuxcnc_real.py runs against LinuxCNC's own linuxcncrsh and milltask — the same
// requests as LinuxCNC itself answers them.
#include <CppUTest/TestHarness.h>

#include <chrono>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "board/sim/linuxcnc_twin.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/sim_board.hpp"
#include "core/models/link_kinds.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/work_zero_link.hpp"
#include "core/net/endpoints.hpp"
#include "drivers/network.hpp"
#include "firmware/links/linuxcnc_link.hpp"
#include "firmware/links/make_link.hpp"
#include "firmware/loop/event_loop.hpp"
#include "tests/unit/link_request.hpp"

using namespace calbox;
using namespace std::chrono_literals;

namespace {

bool logged(const std::vector<std::string>& log, const std::string& part) {
    for (const auto& line : log)
        if (line.find(part) != std::string::npos) return true;
    return false;
}

// A link to linuxcncrsh at `address` (HOST:PORT) with these passwords.
struct LinkUnderTest {
    std::unique_ptr<hal::Network> network = drivers::system_network();
    firmware::EventLoop loop;
    std::vector<std::string> log;
    std::unique_ptr<firmware::LinuxCncLink> link;

    LinkUnderTest(const std::string& address, const std::string& connect,
                  const std::string& enable) {
        const auto at = net::parse_host_port(address, true);
        firmware::LinuxCncSettings s;
        s.host = at.host;
        s.port = at.port;
        s.connect_password = connect;
        s.enable_password = enable;
        s.reply_timeout = 5000ms;
        link = std::make_unique<firmware::LinuxCncLink>(
            s, *network, [this](const std::string& line) { log.push_back(line); });
        link->attach(loop);
    }
    LinkUnderTest(const LinkUnderTest&) = delete;
    LinkUnderTest& operator=(const LinkUnderTest&) = delete;
    ~LinkUnderTest() { link->detach(loop); }
    firmware::JobOutcome commands(const std::vector<std::string>& lines) {
        return run_to_its_end(loop, [&](auto done) { link->send_commands(lines, done); });
    }
    firmware::JobOutcome job(const std::vector<std::string>& lines) {
        return run_to_its_end(loop, [&](auto done) { link->run_job(lines, done); });
    }
};

}  // namespace

TEST_GROUP(LinuxCncLink) {
    std::shared_ptr<sim::TwinBench> bench;
    std::unique_ptr<sim::LinuxCncTwin> twin;
    std::unique_ptr<LinkUnderTest> under_test;

    void start(sim::HostFaults faults = {}) {
        under_test.reset();
        twin.reset();
        bench = std::make_shared<sim::TwinBench>(
            sim::load_scenario(CALBOX_SOURCE_DIR "/examples/router_linuxcnc.toml"));
        twin = std::make_unique<sim::LinuxCncTwin>(bench, "open sesame", faults);
        under_test = std::make_unique<LinkUnderTest>(twin->url(), "open", "sesame");
    }
    void setup() override {
        start();
    }
    void teardown() override {
        under_test.reset();
        twin.reset();
    }
};

TEST(LinuxCncLink, g54s_zero_is_set_by_mdi_and_read_back_where_the_machine_has_it) {
    const geometry::Point2 zero{-247.125, -183.5};
    auto o = under_test->commands(modes::work_zero_units_query("linuxcnc"));
    CHECK_TEXT(o.ok, o.error.c_str());
    STRCMP_EQUAL("", modes::work_zero_units_refusal("linuxcnc", o.replies).c_str());
    o = under_test->commands(modes::work_zero_exchange("linuxcnc", zero));
    CHECK_TEXT(o.ok, o.error.c_str());
    const auto read = modes::work_zero_read_back("linuxcnc", o.replies);
    CHECK_TEXT(read.has_value(), "no POS_OFFSET in the replies");
    DOUBLES_EQUAL(zero.x, read->x, 1e-6);
    DOUBLES_EQUAL(zero.y, read->y, 1e-6);
    // The twin's machine, not the link's echo of it: G54 is where the box said.
    DOUBLES_EQUAL(zero.x, bench->machine_work_zero_mm().x, 1e-9);
    DOUBLES_EQUAL(zero.y, bench->machine_work_zero_mm().y, 1e-9);
    // One connection per request.
    CHECK_EQUAL(2, twin->connections());
}

TEST(LinuxCncLink, an_interpreter_in_inches_is_refused_before_the_zero_goes) {
    auto o = under_test->commands({"G20"});
    CHECK_TEXT(o.ok, o.error.c_str());
    o = under_test->commands(modes::work_zero_units_query("linuxcnc"));
    CHECK_TEXT(o.ok, o.error.c_str());
    STRCMP_CONTAINS("(PROGRAM_UNITS INCH)",
                    modes::work_zero_units_refusal("linuxcnc", o.replies).c_str());
    STRCMP_CONTAINS("did not say",
                    modes::work_zero_units_refusal("linuxcnc", {"POS_OFFSET X 1.0"}).c_str());
    STRCMP_EQUAL("", modes::work_zero_units_refusal("grbl", {}).c_str());
}

TEST(LinuxCncLink, a_job_runs_line_by_line_and_its_program_end_is_sent_as_what_it_does) {
    const auto o = under_test->job({"G21 G90 G54", "G0 X10 Y10", "", "G0 X20 Y5", "M2"});
    CHECK_TEXT(o.ok, o.error.c_str());
    CHECK(logged(under_test->log,
                 "the job's last line 'M2' ends a program, which MDI does not "
                 "run: sent as M5 M9"));
    // An end before the job's last line would cut it short: nothing is sent.
    const auto cut = under_test->job({"G0 X1", "M30", "G0 X2"});
    CHECK_FALSE(cut.ok);
    STRCMP_EQUAL(
        "line 2 'M30' ends the program before its last line: LinuxCNC's MDI runs no "
        "program end",
        cut.error.c_str());
    CHECK_EQUAL(1, twin->connections());
}

TEST(LinuxCncLink, a_line_linuxcnc_refuses_ends_the_request_naming_it_and_linuxcncs_error) {
    const auto o = under_test->job({"G21 G90", "G0 X10 Y1..5", "G0 X20"});
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("LinuxCNC refused line 2 'G0 X10 Y1..5': ", o.error.c_str());
    CHECK(o.error.find("no error text") == std::string::npos);
    // A line linuxcncrsh would cut is refused before anything is sent.
    const auto longest = under_test->commands({"G0 X1 (" + std::string(240, 'a') + ")"});
    CHECK_FALSE(longest.ok);
    STRCMP_EQUAL("line 1 is 248 characters: linuxcncrsh takes 240 at most", longest.error.c_str());
    CHECK_EQUAL(1, twin->connections());
}

TEST(LinuxCncLink, the_passwords_and_a_machine_that_is_off_are_named) {
    sim::HostFaults wrong;
    wrong.wrong_key = true;
    start(wrong);
    auto o = under_test->commands({"get pos_offset X"});
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS(" refused the connect password (linuxcncrsh's --connectpw", o.error.c_str());
    STRCMP_CONTAINS("LinuxCNC at 127.0.0.1:", o.error.c_str());
    // The right connect password and a wrong enable one.
    under_test = std::make_unique<LinkUnderTest>(twin->url(), "open-other", "wrong");
    o = under_test->commands({"get pos_offset X"});
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("refused the enable password (linuxcncrsh's --enablepw", o.error.c_str());
    sim::HostFaults off;
    off.printer_not_ready = true;
    start(off);
    o = under_test->commands({"G0 X1"});
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS(": the machine is not on (MACHINE OFF): release the e-stop", o.error.c_str());
}

TEST(LinuxCncLink, nobody_listening_is_named_with_where_linuxcncrsh_is_started) {
    const std::string address = twin->url();
    under_test.reset();
    twin.reset();  // the port is free again
    under_test = std::make_unique<LinkUnderTest>(address, "open", "sesame");
    const auto o = under_test->commands({"get pos_offset X"});
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS(": Connection refused (is linuxcncrsh running?", o.error.c_str());
}

TEST(LinuxCncLink, a_line_never_done_is_aborted_at_the_reply_timeout) {
    sim::HostFaults silent;
    silent.silent_at_request = 2;
    start(silent);
    const auto started = std::chrono::steady_clock::now();
    const auto o = under_test->job({"G0 X1", "G0 X2"});
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS(": line 2 'G0 X2' not done within 5 s (aborted)", o.error.c_str());
    CHECK(std::chrono::steady_clock::now() - started < 20s);
}

TEST_GROUP(WorkZeroWords){};

TEST(WorkZeroWords, each_controller_sets_g54_and_reports_it_in_its_own_words) {
    const geometry::Point2 zero{-250, -180.5};
    STRCMP_EQUAL("G10 L2 P1 X-250.000 Y-180.500", modes::work_zero_command(zero).c_str());
    const auto grbl = modes::work_zero_exchange("grbl", zero);
    CHECK_EQUAL(2u, grbl.size());
    STRCMP_EQUAL("$#", grbl[1].c_str());
    const auto read = modes::work_zero_read_back(
        "grbl", {"[G54:-250.000,-180.500,0.000]", "[G55:0.000,0.000,0.000]"});
    CHECK(read.has_value());
    DOUBLES_EQUAL(-180.5, read->y, 1e-9);
    // linuxcncrsh's POS_OFFSET as LinuxCNC 2.9 prints it (two blanks before the number).
    const auto lcnc = modes::work_zero_read_back(
        "linuxcnc", {"POS_OFFSET X  -250.000000", "POS_OFFSET Y  -180.500000"});
    CHECK(lcnc.has_value());
    DOUBLES_EQUAL(-250, lcnc->x, 1e-9);
    CHECK_FALSE(modes::work_zero_read_back("linuxcnc", {"POS_OFFSET X 1.0"}).has_value());
    CHECK(modes::sets_work_zero("linuxcnc"));
    CHECK_FALSE(modes::sets_work_zero("marlin"));
}

// LinuxCNC itself (tests/network/linuxcnc_real.py starts its simulated mill, homes it, and runs
// this group with CALBOX_LINUXCNC=HOST:PORT; linuxcncrsh's default passwords).
TEST_GROUP(LinuxCncReal) {
    std::unique_ptr<LinkUnderTest> under_test;
    void setup() override {
        const char* at = std::getenv("CALBOX_LINUXCNC");
        if (at == nullptr) FAIL("CALBOX_LINUXCNC (HOST:PORT of a running linuxcncrsh) is not set");
        under_test = std::make_unique<LinkUnderTest>(at, "EMC", "EMCTOO");
    }
};

TEST(LinuxCncReal, linuxcnc_takes_g54_by_mdi_and_reports_it_back) {
    auto o = under_test->commands(modes::work_zero_units_query("linuxcnc"));
    CHECK_TEXT(o.ok, o.error.c_str());
    STRCMP_EQUAL("", modes::work_zero_units_refusal("linuxcnc", o.replies).c_str());
    const geometry::Point2 zero{12.5, -3.25};
    o = under_test->commands(modes::work_zero_exchange("linuxcnc", zero));
    CHECK_TEXT(o.ok, o.error.c_str());
    const auto read = modes::work_zero_read_back("linuxcnc", o.replies);
    CHECK_TEXT(read.has_value(), "LinuxCNC's replies hold no POS_OFFSET");
    DOUBLES_EQUAL(12.5, read->x, 1e-6);
    DOUBLES_EQUAL(-3.25, read->y, 1e-6);
    // Another zero, so that the first cannot have been there already.
    o = under_test->commands(modes::work_zero_exchange("linuxcnc", {-7.125, 4}));
    CHECK_TEXT(o.ok, o.error.c_str());
    DOUBLES_EQUAL(-7.125, modes::work_zero_read_back("linuxcnc", o.replies)->x, 1e-6);
}

TEST(LinuxCncReal, a_job_runs_by_mdi_and_linuxcncs_refusals_are_named) {
    auto o = under_test->job({"G21 G90 G54", "G0 X1 Y1", "G1 X2 Y2 F600", "M2"});
    CHECK_TEXT(o.ok, o.error.c_str());
    CHECK(logged(under_test->log, "sent as M5 M9"));
    o = under_test->job({"G21 G90", "G1 X2 Q5 F100"});
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("LinuxCNC refused line 2 'G1 X2 Q5 F100': Q word with no G5", o.error.c_str());
    o = under_test->job({"G21 G90 G53 G0 X99999"});
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("would exceed X's positive limit", o.error.c_str());
    // The inches check reads what LinuxCNC says, and LinuxCNC is put back in millimetres.
    o = under_test->commands({"G20", "get program_units", "G21"});
    CHECK_TEXT(o.ok, o.error.c_str());
    STRCMP_CONTAINS("(PROGRAM_UNITS INCH)",
                    modes::work_zero_units_refusal("linuxcnc", o.replies).c_str());
}

// The link kinds, declared once (core/models/link_kinds.hpp): the machine file's reader and the
// configuration take every kind from the table, and each host kind refuses another firmware in
// the table's words. (A factory or a twin missing for a kind fails the build: make_link.cpp's and
// sim_board.cpp's static_asserts.)
TEST_GROUP(LinkKinds){};

TEST(LinkKinds, every_kind_is_read_from_the_machine_file_and_refuses_another_firmware) {
    const auto file = [](const std::string& firmware, const std::string& kind) {
        return "[machine]\nkind = \"router\"\nfirmware = \"" + firmware +
               "\"\nbed_size_x_mm = 300\nbed_size_y_mm = 300\n[link]\nkind = \"" + kind + "\"\n";
    };
    for (const auto& k : models::kLinkKinds) {
        const std::string kind(k.name);
        const std::string firmware = k.firmware.empty() ? "grbl" : std::string(k.firmware);
        CHECK_TEXT(models::parse_machine_file(file(firmware, kind), "m.toml").link.kind == kind,
                   kind.c_str());
        CHECK_EQUAL(k.host,
                    models::parse_machine_file(file(firmware, kind), "m.toml").link.is_host());
        if (k.firmware.empty()) continue;
        const std::string other = firmware == "grbl" ? "marlin" : "grbl";
        try {
            models::parse_machine_file(file(other, kind), "m.toml");
            FAIL(("[link] kind = " + kind + " was taken for " + other).c_str());
        } catch (const models::MachineFileError& e) {
            STRCMP_CONTAINS((std::string(k.serves) + " ([machine] firmware = \"" + firmware +
                             "\", not \"" + other + "\")")
                                .c_str(),
                            e.what());
        }
    }
    STRCMP_EQUAL("serial|moonraker|octoprint|duet|linuxcnc", models::link_kind_list("|").c_str());
    STRCMP_EQUAL("moonraker, octoprint, duet, linuxcnc",
                 models::link_kind_list(", ", true).c_str());
}

TEST(LinkKinds, the_configurations_link_kind_offers_every_kind) {
    const auto table = firmware::link_settings_table();
    const auto& kind = table.keys.front();
    STRCMP_EQUAL("kind", std::string(kind.info.name).c_str());
    firmware::LinkSettings s;
    for (const auto& k : models::kLinkKinds) {
        kind.set(s, kind.info, k.name);
        STRCMP_EQUAL(std::string(k.name).c_str(), s.kind.c_str());
    }
    kind.set(s, kind.info, "machine");
    CHECK_THROWS(firmware::ConfigError, kind.set(s, kind.info, "telnet"));
}
