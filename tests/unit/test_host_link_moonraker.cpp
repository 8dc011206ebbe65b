// The Moonraker link against the twin's host: commands and their replies, printer.cfg read and
// replaced, a job run; each fault ends its request with one line naming it.
#include "tests/unit/host_link_rig.hpp"

// The link against the twin's host: commands and their replies, the settings in force, the
// file read and replaced only while it is the one read, a job uploaded and run; each fault
// ends its request with one line naming it.
TEST_GROUP(MoonrakerLink) {
    fs::path dir;
    std::unique_ptr<hal::Network> network = drivers::system_network();
    std::shared_ptr<sim::TwinBench> bench;
    std::unique_ptr<sim::MoonrakerTwin> host;
    std::unique_ptr<firmware::MoonrakerLink> link;
    firmware::EventLoop loop;
    std::vector<std::string> log;

    void setup() override {
        dir = fs::temp_directory_path() / ("calbox-moonraker-" + std::to_string(::getpid()));
        fs::remove_all(dir);
        fs::create_directories(dir);
    }
    void teardown() override {
        if (link) link->detach(loop);
        link.reset();
        host.reset();
        fs::remove_all(dir);
    }

    void start(const sim::HostFaults& faults, const std::string& key = "sesame",
               const std::string& link_key = "sesame",
               const char* example = CALBOX_SOURCE_DIR "/examples/moonraker_delta.toml") {
        auto scenario = sim::load_scenario(example);
        bench = std::make_shared<sim::TwinBench>(scenario);
        host = std::make_unique<sim::MoonrakerTwin>(bench, dir / "host",
                                                    sim::TwinHostSettings{key, faults, 85, 0});
        firmware::MoonrakerSettings s;
        s.url = net::parse_url(host->url());
        s.api_key = link_key;
        s.reply_timeout = 1500ms;
        s.restart_timeout = 5000ms;
        s.poll_interval = 20ms;
        link = std::make_unique<firmware::MoonrakerLink>(
            s, network->http(), [this](const std::string& line) { log.push_back(line); });
        link->attach(loop);
    }

    template <class Start>
    firmware::JobOutcome await(Start start_request) {
        return run_to_its_end(loop, start_request);
    }

    std::string host_config() const {
        std::ifstream in(dir / "host" / "printer.cfg");
        std::ostringstream s;
        s << in.rdbuf();
        return s.str();
    }
};

TEST(MoonrakerLink, commands_settings_and_printer_cfg_through_the_host) {
    start({});
    auto o = await([&](auto done) { link->send_commands({"G28", "M400"}, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    o = await([&](auto done) { link->send_commands({"M665 L250"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("unknown command", o.error.c_str());

    o = await([&](auto done) { link->read_settings_in_force(done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    STRCMP_CONTAINS("[stepper_b]", o.text.c_str());
    STRCMP_CONTAINS("delta_radius: 140", o.text.c_str());

    const auto before = await([&](auto done) { link->read_config_file(done); });
    STRCMP_EQUAL(host_config().c_str(), before.text.c_str());
    // Written only while the host still holds the file the box read.
    o = await([&](auto done) { link->replace_config_file("x", before.text + "#", done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("changed on the host", o.error.c_str());
    STRCMP_EQUAL(before.text.c_str(), host_config().c_str());

    auto g = example_geometry();
    const std::string updated = models::klipper_saved_config(before.text, g);
    o = await([&](auto done) { link->replace_config_file(updated, before.text, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    STRCMP_EQUAL(updated.c_str(), host_config().c_str());
    // The twin printer took it at its restart.
    const auto firmware = bench->delta_printer_firmware();
    DOUBLES_EQUAL(139.2, firmware.radius_mm, 1e-9);
    DOUBLES_EQUAL(251.5, firmware.diagonal_rod_mm + firmware.diagonal_rod_trim_mm[0], 1e-9);
    // One websocket all along, opened with a one-shot token: the key never went over it.
    LONGS_EQUAL(1, host->tokens_redeemed());
}

// A one-shot token opens one websocket: used again, or without the key that fetched it, refused.
namespace {

// The cycle's side of a mode's request, as the cycle does it: through the link, on the loop; a
// failure only recorded.
class StepsOverLink : public firmware::CycleSteps {
  public:
    StepsOverLink(firmware::MachineLink& link, firmware::EventLoop& loop)
        : link_(link), loop_(loop) {}
    std::vector<std::string> failures;

    void work(std::function<void()> job, std::function<void()> then) override {
        job();
        then();
    }
    void run_job(const std::vector<std::string>& lines,
                 std::function<void(const firmware::JobOutcome&)> then) override {
        send_commands(lines, std::move(then));
    }
    void ask_machine(std::function<void(firmware::MachineLink&, firmware::MachineLink::Done)> start,
                     std::function<void(const firmware::JobOutcome&)> then,
                     bool failure_is_error) override {
        const auto o = run_to_its_end(loop_, [&](auto done) { start(link_, done); });
        if (!o.ok && failure_is_error) return fail(o.error);
        then(o);
    }
    const firmware::MachineLink& machine_link() const override { return link_; }
    bool keep(const std::string&, const std::string&) override { return true; }
    std::optional<std::string> read(const std::string&) const override { return std::nullopt; }
    std::string record_name(const std::string& what) const override { return what; }
    void enter(firmware::CycleState, const std::string&) override {}
    void log(const std::string&, hal::LogLevel) override {}
    void log_detail(const std::string&) override {}
    void notice(const std::string&) override {}
    void fail(const std::string& message) override { failures.push_back(message); }

  private:
    firmware::MachineLink& link_;
    firmware::EventLoop& loop_;
};

}  // namespace

// What both Klipper modes share: a Klipper printer behind Moonraker is recognised, its settings in
// force reach the mode as the mode reads them, and settings the mode cannot read (a delta's, read
// as a cartesian printer's) put the cycle in error with the reader's line, the mode never called.
TEST(MoonrakerLink, the_modes_read_klippers_settings_in_force_or_fail_the_cycle_with_why) {
    start({});
    StepsOverLink steps(*link, loop);
    auto machine = sim::load_scenario(CALBOX_SOURCE_DIR "/examples/moonraker_delta.toml").machine;
    CHECK_TRUE(steps.klipper_on_host(machine));
    machine.firmware = "marlin";
    CHECK_FALSE(steps.klipper_on_host(machine));

    std::optional<models::DeltaGeometry> read;
    steps.read_settings_in_force<models::DeltaGeometry>(
        [](const std::string& text) {
            return models::from_klipper(
                models::read_klipper_config("in force", text, [](const std::string&) {
                    return std::optional<std::string>();
                }).delta);
        },
        [&](models::DeltaGeometry g) { read = g; });
    CHECK_TRUE(read.has_value());
    // The printer's settings in examples/moonraker_delta.toml, as Klipper holds them.
    DOUBLES_EQUAL(300.1069, read->height_mm, 1e-6);
    DOUBLES_EQUAL(250.0, read->diagonal_rod_mm, 1e-9);
    CHECK_TRUE(steps.failures.empty());

    bool called = false;
    steps.read_settings_in_force<models::KlipperCartesian>(
        [](const std::string& text) { return models::read_klipper_cartesian("in force", text); },
        [&](models::KlipperCartesian) { called = true; });
    CHECK_FALSE(called);
    LONGS_EQUAL(1, static_cast<long>(steps.failures.size()));
    STRCMP_CONTAINS("in force", steps.failures[0].c_str());
    STRCMP_CONTAINS("cartesian", steps.failures[0].c_str());
}

TEST(MoonrakerLink, a_one_shot_token_opens_one_websocket) {
    start({});
    const auto url = net::parse_url(host->url());
    const auto fetched = drivers::http_request(
        url, {"GET", "/access/oneshot_token", {{"X-Api-Key", "sesame"}}, {}, {}}, 2000ms);
    LONGS_EQUAL(200, fetched.status);
    const std::string token = nlohmann::json::parse(fetched.body)["result"];
    auto socket_url = url;
    socket_url.path = "/websocket?token=" + token;
    drivers::WebSocketClient first(socket_url, {}, 2000ms);
    try {
        drivers::WebSocketClient again(socket_url, {}, 2000ms);
        FAIL("a one-shot token opened a second websocket");
    } catch (const hal::NetworkError& e) {
        STRCMP_CONTAINS("401", e.what());
    }
    const auto refused =
        drivers::http_request(url, {"GET", "/access/oneshot_token", {}, {}, {}}, 2000ms);
    LONGS_EQUAL(401, refused.status);
    LONGS_EQUAL(1, host->tokens_redeemed());
}

// A cartesian printer's skew: saved by Klipper itself (SAVE_CONFIG and its restart awaited), in
// force only once loaded, read back from configfile.settings.
TEST(MoonrakerLink, klipper_saves_the_skew_and_puts_it_in_force_when_loaded) {
    start({}, "sesame", "sesame", CALBOX_SOURCE_DIR "/examples/moonraker_cartesian.toml");
    const auto saved = await(
        [this](auto done) { link->save_config_after(models::klipper_skew_commands(0.004), done); });
    CHECK_TEXT(saved.ok, saved.error.c_str());
    STRCMP_CONTAINS("#*# [skew_correction calbox]\n#*# xy_skew = 0.00399999",
                    host_config().c_str());
    // Klipper starts with no skew in force.
    DOUBLES_EQUAL(0, bench->cartesian_printer_firmware().xy_skew, 0);
    const auto loaded =
        await([this](auto done) { link->send_commands({"SKEW_PROFILE LOAD=calbox"}, done); });
    CHECK_TEXT(loaded.ok, loaded.error.c_str());
    DOUBLES_EQUAL(0.004, bench->cartesian_printer_firmware().xy_skew, 1e-8);
    const auto in_force = await([this](auto done) { link->read_settings_in_force(done); });
    CHECK_TEXT(in_force.ok, in_force.error.c_str());
    const auto k = models::read_klipper_cartesian("settings", in_force.text);
    DOUBLES_EQUAL(0.004, k.xy_skew.value_or(0), 1e-8);
    DOUBLES_EQUAL(40, k.rotation_distance_x_mm, 0);
    const auto unknown =
        await([this](auto done) { link->send_commands({"SKEW_PROFILE LOAD=other"}, done); });
    CHECK_FALSE(unknown.ok);
    STRCMP_CONTAINS("unknown profile [other]", unknown.error.c_str());
}

TEST(MoonrakerLink, a_job_is_uploaded_started_and_followed_to_its_end) {
    start({});
    auto o = await([&](auto done) { link->run_job({"G28", "G1 X10 Y10 Z5 F3000"}, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    CHECK(fs::exists(dir / "host" / "gcodes" / "calbox-target.gcode"));
    o = await([&](auto done) { link->run_job({"M665 L250"}, done); });  // not Klipper's
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("the print failed on the host", o.error.c_str());
}

TEST(MoonrakerLink, a_wrong_key_is_named) {
    start({}, "sesame", "open");
    const auto o = await([&](auto done) { link->send_commands({"G28"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("HTTP 401", o.error.c_str());
    STRCMP_CONTAINS("API key", o.error.c_str());
    CHECK(o.error.find("open") == std::string::npos);
}

TEST(MoonrakerLink, klipper_not_ready_is_named) {
    sim::HostFaults f;
    f.printer_not_ready = true;
    start(f);
    const auto o = await([&](auto done) { link->read_settings_in_force(done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("Klipper is not ready (startup: mcu 'mcu': Unable to connect)",
                    o.error.c_str());
}

TEST(MoonrakerLink, a_host_that_never_replies_times_out) {
    sim::HostFaults f;
    f.silent_at_request = 3;  // identify, printer.info, then silence
    start(f);
    const auto o = await([&](auto done) { link->send_commands({"G28"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("no reply to printer.gcode.script within 1 s", o.error.c_str());
}

TEST(MoonrakerLink, a_host_restarting_mid_request_is_named_and_the_next_request_reconnects) {
    sim::HostFaults f;
    f.restart_at_request = 3;
    start(f);
    auto o = await([&](auto done) { link->send_commands({"G28"}, done); });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS("Moonraker: ", o.error.c_str());
    std::this_thread::sleep_for(1600ms);  // the twin host's restart
    o = await([&](auto done) { link->send_commands({"G28"}, done); });
    CHECK_TEXT(o.ok, o.error.c_str());
    // Each connection its own token.
    LONGS_EQUAL(2, host->tokens_redeemed());
}

TEST(MoonrakerLink, a_print_cancelled_on_the_host_is_named) {
    sim::HostFaults f;
    f.print_cancelled = true;
    start(f);
    const auto o = await([&](auto done) {
        link->run_job({"G28", "G1 X1 Z5", "G1 X2 Z5", "G1 X3 Z5", "G1 X4 Z5"}, done);
    });
    CHECK_FALSE(o.ok);
    STRCMP_EQUAL("the print was cancelled on the host", o.error.c_str());
}

TEST(MoonrakerLink, a_refused_upload_leaves_the_file_as_it_was) {
    sim::HostFaults f;
    f.upload_refused = true;
    start(f);
    const auto before = await([&](auto done) { link->read_config_file(done); });
    const auto o = await([&](auto done) {
        link->replace_config_file(models::klipper_saved_config(before.text, example_geometry()),
                                  before.text, done);
    });
    CHECK_FALSE(o.ok);
    STRCMP_CONTAINS(
        "the host refused the upload of printer.cfg (HTTP 400: Insufficient disk space)",
        o.error.c_str());
    STRCMP_EQUAL(before.text.c_str(), host_config().c_str());
}
