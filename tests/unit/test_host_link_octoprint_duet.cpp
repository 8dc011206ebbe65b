// The OctoPrint and Duet links against the twins' hosts: replies read between the markers the
// firmware echoes, a job uploaded and followed to its end, each fault one line.
#include "tests/unit/host_link_rig.hpp"

// The OctoPrint link against the twin's OctoPrint: Marlin's answers read between the markers it
// echoes, a job uploaded with print=true and followed to its end, a key asked for through the
// application keys plugin.
TEST_GROUP(OctoPrintLink) {
    fs::path dir;
    std::unique_ptr<hal::Network> network = drivers::system_network();
    std::shared_ptr<sim::TwinBench> bench;
    std::unique_ptr<sim::OctoPrintTwin> host;
    std::unique_ptr<firmware::OctoPrintLink> link;
    firmware::EventLoop loop;
    std::vector<std::string> log;

    void setup() override {
        dir = fs::temp_directory_path() / ("calbox-octoprint-" + std::to_string(::getpid()));
        fs::remove_all(dir);
        fs::create_directories(dir);
        bench = std::make_shared<sim::TwinBench>(
            sim::load_scenario(CALBOX_SOURCE_DIR "/examples/octoprint_delta.toml"));
        host = std::make_unique<sim::OctoPrintTwin>(bench, dir / "host",
                                                    sim::TwinHostSettings{"sesame", {}, 85, 0});
        firmware::OctoPrintSettings s;
        s.url = net::parse_url(host->url());
        s.api_key = "sesame";
        s.reply_timeout = 2000ms;
        s.poll_interval = 20ms;
        link = std::make_unique<firmware::OctoPrintLink>(
            s, network->http(), [this](const std::string& line) { log.push_back(line); });
        link->attach(loop);
    }
    void teardown() override {
        link->detach(loop);
        link.reset();
        host.reset();
        fs::remove_all(dir);
    }
    template <class Start>
    firmware::JobOutcome await(Start start_request) {
        return run_to_its_end(loop, start_request);
    }
};

TEST(OctoPrintLink, marlins_answers_come_between_the_markers) {
    auto o = await([&](auto done) { link->send_commands({"M503"}, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    // M503's delta lines, nothing of the markers or the oks.
    bool m665 = false;
    for (const auto& r : o.replies) {
        CHECK(r.find("calbox-") == std::string::npos);
        CHECK(r != "ok");
        m665 = m665 || r.find("M665 L250.000 R140.000") != std::string::npos;
    }
    CHECK_TEXT(m665, "no M665 in the reply to M503");
    // A second batch reads only its own answers.
    o = await([&](auto done) { link->send_commands({"M665 L251 R140", "M503"}, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    bool changed = false;
    for (const auto& r : o.replies)
        changed = changed || r.find("M665 L251.000") != std::string::npos;
    CHECK_TEXT(changed, "the second batch's M503 does not show its M665");
    // Marlin refusing a line is the request's error.
    o = await([&](auto done) { link->send_commands({"G1 X10"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("the printer: Error:", o.error.c_str());
}

TEST(OctoPrintLink, a_job_is_uploaded_printed_and_followed_to_its_end) {
    const auto o = await([&](auto done) { link->run_job({"G28", "G1 X10 Y10 Z5 F3000"}, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    CHECK(fs::exists(dir / "host" / "uploads" / "calbox-target.gcode"));
}

// The host takes the job and never starts it: named once the reply timeout (2 s here) has
// passed without the print seen under way, the host's state in the line.
TEST(OctoPrintLink, a_print_the_host_never_starts_is_named) {
    link->detach(loop);
    link.reset();
    host.reset();
    sim::HostFaults faults;
    faults.print_never_starts = true;
    host = std::make_unique<sim::OctoPrintTwin>(bench, dir / "host",
                                                sim::TwinHostSettings{"sesame", faults, 85, 0});
    firmware::OctoPrintSettings s;
    s.url = net::parse_url(host->url());
    s.api_key = "sesame";
    s.reply_timeout = 500ms;
    s.poll_interval = 20ms;
    link = std::make_unique<firmware::OctoPrintLink>(s, network->http(), [](const std::string&) {});
    link->attach(loop);
    const auto o = await([&](auto done) { link->run_job({"G28"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_EQUAL("the print never started on the host (Operational)", o.error.c_str());
}

TEST(OctoPrintLink, a_key_is_asked_for_through_the_application_keys_plugin) {
    std::vector<std::string> said;
    const auto key =
        firmware::request_octoprint_key(network->http(), net::parse_url(host->url()), "owner", 10s,
                                        [&said](const std::string& line) { said.push_back(line); });
    STRCMP_EQUAL("sesame", key.c_str());
    CHECK_EQUAL(1u, said.size());
    STRCMP_CONTAINS("allow calbox's access", said[0].c_str());
}

// The Duet link against the twin's Duet: the password for a session, replies read up to the
// marker, a job uploaded with its CRC32 and started with M32.
TEST_GROUP(DuetLink) {
    fs::path dir;
    std::unique_ptr<hal::Network> network = drivers::system_network();
    std::shared_ptr<sim::TwinBench> bench;
    std::unique_ptr<sim::DuetTwin> host;
    std::unique_ptr<firmware::DuetLink> link;
    firmware::EventLoop loop;

    void setup() override {
        dir = fs::temp_directory_path() / ("calbox-duet-" + std::to_string(::getpid()));
        fs::remove_all(dir);
        fs::create_directories(dir);
        bench = std::make_shared<sim::TwinBench>(
            sim::load_scenario(CALBOX_SOURCE_DIR "/examples/duet_delta.toml"));
        serve(false, {});
    }
    // The board: standalone, or with an SBC.
    void serve(bool sbc, const sim::HostFaults& faults) {
        host.reset();
        host = std::make_unique<sim::DuetTwin>(
            bench, dir / "host", sim::TwinHostSettings{"pass word", faults, 85, 0, sbc});
    }
    void connect(const std::string& password) {
        firmware::DuetSettings s;
        s.url = net::parse_url(host->url());
        s.password = password;
        s.reply_timeout = 2000ms;
        s.poll_interval = 20ms;
        link = std::make_unique<firmware::DuetLink>(s, network->http(), [](const std::string&) {});
        link->attach(loop);
    }
    void teardown() override {
        if (link) link->detach(loop);
        link.reset();
        host.reset();
        fs::remove_all(dir);
    }
    template <class Start>
    firmware::JobOutcome await(Start start_request) {
        return run_to_its_end(loop, start_request);
    }
};

TEST(DuetLink, query_values_are_percent_encoded) {
    STRCMP_EQUAL("M665%20L250%3A250%3A250%20R140",
                 firmware::url_encoded("M665 L250:250:250 R140").c_str());
    STRCMP_EQUAL("M118%20S%22a-b_c.d~%22", firmware::url_encoded("M118 S\"a-b_c.d~\"").c_str());
}

TEST(DuetLink, rrf_reports_its_settings_through_the_board) {
    connect("pass word");
    auto o = await([&](auto done) { link->send_commands({"M665", "M666"}, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    CHECK_EQUAL(2u, o.replies.size());
    STRCMP_CONTAINS("Diagonals 250.000:250.000:250.000, delta radius 140.000",
                    o.replies[0].c_str());
    STRCMP_CONTAINS("Endstop adjustments X0.00 Y0.00 Z0.00", o.replies[1].c_str());
    o = await([&](auto done) { link->run_job({"G28", "G1 X10 Y10 Z5 F3000"}, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    CHECK(fs::exists(dir / "host" / "gcodes" / "calbox-target.gcode"));
    o = await([&](auto done) { link->send_commands({"M999 P\"unknown\""}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("the printer: Error:", o.error.c_str());
}

// M32 taken but the print never started: named after the reply timeout (2 s here).
TEST(DuetLink, a_print_the_board_never_starts_is_named) {
    sim::HostFaults faults;
    faults.print_never_starts = true;
    serve(false, faults);
    connect("pass word");
    const auto o = await([&](auto done) { link->run_job({"G28"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_EQUAL("the print never started on the host (idle)", o.error.c_str());
}

// The same requests to a board with an SBC: the link finds DuetSoftwareFramework's API (the board
// answers no rr_connect) and closes its session when it goes, as on a standalone board.
TEST(DuetLink, a_board_with_an_sbc_is_reached_through_its_machine_api) {
    for (const bool sbc : {false, true}) {
        serve(sbc, {});
        connect("pass word");
        auto o = await([&](auto done) { link->send_commands({"M665", "M666"}, done); });
        CHECK_TEXT(o.ok, o.error.c_str());
        CHECK_EQUAL(2u, o.replies.size());
        STRCMP_CONTAINS("Diagonals 250.000:250.000:250.000, delta radius 140.000",
                        o.replies[0].c_str());
        o = await([&](auto done) { link->run_job({"G28", "G1 X10 Y10 Z5 F3000"}, done); });
        CHECK_TEXT(o.ok, o.error.c_str());
        STRCMP_EQUAL("G28\nG1 X10 Y10 Z5 F3000\n",
                     sim::read_whole_file(dir / "host" / "gcodes" / "calbox-target.gcode").c_str());
        o = await([&](auto done) { link->send_commands({"M999 P\"unknown\""}, done); });
        CHECK_FALSE(o.ok);
        STRCMP_CONTAINS("the printer: Error:", o.error.c_str());
        LONGS_EQUAL(0, host->sessions_closed());
        link->detach(loop);
        link.reset();
        LONGS_EQUAL(1, host->sessions_closed());
        fs::remove(dir / "host" / "gcodes" / "calbox-target.gcode");
    }
    serve(true, {});
    connect("guess");
    auto o = await([&](auto done) { link->send_commands({"M665"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_EQUAL("Duet: the board refused the password (is key_file's the board's M551?)",
                 o.error.c_str());
    link->detach(loop);
    link.reset();
    sim::HostFaults refuse;
    refuse.upload_refused = true;
    serve(true, refuse);
    connect("pass word");
    o = await([&](auto done) { link->run_job({"G28"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_EQUAL(
        "the host refused the upload of calbox-target.gcode (/machine/file: HTTP 500: Not enough "
        "space on the SD card)",
        o.error.c_str());
}

// A board that never answers rr_connect: the error names the request, not its query (which
// carries the password).
TEST(DuetLink, a_password_is_never_in_an_error) {
    sim::HostFaults silent;
    silent.silent_at_request = 1;
    serve(false, silent);
    connect("pass word");
    const auto o = await([&](auto done) { link->send_commands({"M665"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("the reply to /rr_connect: none within 2000 ms", o.error.c_str());
    CHECK(o.error.find("pass") == std::string::npos);
}

TEST(DuetLink, a_wrong_password_is_named_and_never_shown) {
    connect("guess");
    const auto o = await([&](auto done) { link->send_commands({"M665"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_EQUAL("Duet: the board refused the password (is key_file's the board's M551?)",
                 o.error.c_str());
}
