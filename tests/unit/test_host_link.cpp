// A printer behind a host: the HTTP and WebSocket driver on loopback, printer.cfg's SAVE_CONFIG
// block as the box writes it, the twin's own reading of printer.cfg, and the Moonraker link
// against the twin's host (faults included).
#include <CppUTest/TestHarness.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <thread>

#include "board/sim/duet_twin.hpp"
#include "board/sim/moonraker_twin.hpp"
#include "board/sim/octoprint_twin.hpp"
#include "board/sim/scenario.hpp"
#include "board/sim/sim_board.hpp"
#include "core/models/delta_commands.hpp"
#include "core/models/klipper_config.hpp"
#include "core/models/machine_file.hpp"
#include "core/models/machine_import.hpp"
#include "drivers/http_client.hpp"
#include "drivers/http_server.hpp"
#include "drivers/network.hpp"
#include "drivers/tls.hpp"
#include "firmware/cycle/cycle_mode.hpp"
#include "firmware/links/duet_link.hpp"
#include "firmware/links/moonraker_link.hpp"
#include "firmware/links/octoprint_link.hpp"
#include "firmware/loop/event_loop.hpp"
#include "tests/unit/link_request.hpp"

using namespace calbox;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

TEST_GROUP(HttpDriver){};

TEST(HttpDriver, parses_urls_and_refuses_what_it_cannot_reach) {
    const auto u = net::parse_url("http://printer.local:7125/api");
    STRCMP_EQUAL("http", u.scheme.c_str());
    STRCMP_EQUAL("printer.local", u.host.c_str());
    STRCMP_EQUAL("7125", u.port.c_str());
    STRCMP_EQUAL("/api", u.path.c_str());
    STRCMP_EQUAL("80", net::parse_url("http://10.0.0.5").port.c_str());
    CHECK_THROWS(std::invalid_argument, net::parse_url("printer.local:7125"));
    CHECK_THROWS(std::invalid_argument, net::parse_url("ftp://printer.local"));
    CHECK_THROWS(std::invalid_argument, net::parse_url("http://printer.local:99999"));
    CHECK_THROWS(std::invalid_argument, net::parse_url("http://user:pw@printer.local"));
    const auto tls = net::parse_url("https://printer.local/");
    CHECK(tls.tls());
    STRCMP_EQUAL("443", tls.port.c_str());
    CHECK(net::parse_url("wss://printer.local:7125/websocket").tls());
    CHECK_FALSE(u.tls());
}

// HTTPS and WSS to a server behind a TLS terminator (a host behind its reverse proxy): reached
// when the client trusts the server's certificate, refused naming TLS when it does not, and when
// the certificate names another host.
TEST(HttpDriver, tls_reaches_a_host_whose_certificate_it_trusts_and_no_other) {
    drivers::HttpServer server(
        "127.0.0.1", 0,
        {[](const hal::ServerRequest& r) {
             return hal::ServerResponse{200, "text/plain", r.method + " " + r.target};
         },
         [](const hal::ServerRequest&) { return 101; },
         [](const hal::ServerRequest&, const std::string& m) {
             return std::vector<std::string>{"re:" + m};
         }});
    const auto certificate = drivers::self_signed_certificate({"127.0.0.1"}, 1);
    STRCMP_CONTAINS("-----BEGIN CERTIFICATE-----", certificate.certificate_pem.c_str());
    drivers::TlsTerminator front("127.0.0.1", server.port(), certificate);
    const fs::path ca = fs::temp_directory_path() / ("calbox-ca-" + std::to_string(::getpid()));
    { std::ofstream(ca) << certificate.certificate_pem; }
    auto url = net::parse_url("https://127.0.0.1:" + std::to_string(front.port()));
    url.ca_file = ca.string();
    const auto r = drivers::http_request(url, {"GET", "/server/info", {}, {}, {}}, 2000ms);
    CHECK_EQUAL(200, r.status);
    STRCMP_EQUAL("GET /server/info", r.body.c_str());
    auto socket_url = net::parse_url("wss://127.0.0.1:" + std::to_string(front.port()) + "/ws");
    socket_url.ca_file = ca.string();
    drivers::WebSocketClient ws(socket_url, {}, 2000ms);
    ws.send("hello");
    STRCMP_EQUAL("re:hello", ws.receive(2000ms).value().c_str());
    // The inner server dropping its connections drops the TLS one too.
    server.drop_connections();
    CHECK_THROWS(hal::NetworkError, ws.receive(2000ms));

    // Without the certificate to trust (the system's authorities never signed it).
    auto untrusted = url;
    untrusted.ca_file.clear();
    try {
        drivers::http_request(untrusted, {"GET", "/", {}, {}, {}}, 2000ms);
        FAIL("a certificate nobody vouches for was taken");
    } catch (const hal::NetworkError& e) {
        STRCMP_CONTAINS("TLS: certificate verify failed", e.what());
    }
    // A certificate for another address.
    const auto other = drivers::self_signed_certificate({"127.0.0.2"}, 1);
    drivers::TlsTerminator elsewhere("127.0.0.1", server.port(), other);
    { std::ofstream(ca) << other.certificate_pem; }
    auto misnamed = net::parse_url("https://127.0.0.1:" + std::to_string(elsewhere.port()));
    misnamed.ca_file = ca.string();
    try {
        drivers::http_request(misnamed, {"GET", "/", {}, {}, {}}, 2000ms);
        FAIL("a certificate for another host was taken");
    } catch (const hal::NetworkError& e) {
        STRCMP_CONTAINS("TLS: certificate verify failed", e.what());
    }
    fs::remove(ca);
}

// A request and a websocket exchange through the server, as the twin host and the link use
// them; a refused upgrade names its status; a read that gets nothing gives nothing, and the
// message that comes later is not lost.
TEST(HttpDriver, serves_and_reaches_http_and_websocket_on_loopback) {
    drivers::HttpServer server(
        "127.0.0.1", 0,
        {[](const hal::ServerRequest& r) {
             return hal::ServerResponse{
                 r.target == "/echo" ? 200 : 404, "text/plain",
                 r.method + " " + r.body + " " +
                     (r.headers.count("x-api-key") != 0 ? r.headers.at("x-api-key")
                                                        : std::string("-"))};
         },
         [](const hal::ServerRequest& r) { return r.headers.count("x-api-key") != 0 ? 101 : 401; },
         [](const hal::ServerRequest&, const std::string& m) {
             if (m == "quiet") return std::vector<std::string>{};
             return std::vector<std::string>{"1:" + m, "2:" + m};
         }});
    const auto url = net::parse_url("http://127.0.0.1:" + std::to_string(server.port()));
    const auto r = drivers::http_request(
        url, {"POST", "/echo", {{"X-Api-Key", "k1"}}, "text/plain", "body"}, 2000ms);
    CHECK_EQUAL(200, r.status);
    STRCMP_EQUAL("POST body k1", r.body.c_str());
    CHECK_EQUAL(404, drivers::http_request(url, {"GET", "/other", {}, {}, {}}, 2000ms).status);

    try {
        drivers::WebSocketClient refused(url, {}, 2000ms);
        FAIL("the upgrade without a key was accepted");
    } catch (const hal::NetworkError& e) {
        STRCMP_CONTAINS("HTTP 401", e.what());
    }
    drivers::WebSocketClient ws(url, {{"X-Api-Key", "k1"}}, 2000ms);
    ws.send("quiet");
    CHECK_FALSE(ws.receive(100ms).has_value());
    ws.send("hello");
    STRCMP_EQUAL("1:hello", ws.receive(2000ms).value().c_str());
    STRCMP_EQUAL("2:hello", ws.receive(2000ms).value().c_str());
    // What the server pushes on its own (a host's terminal log) reaches every open socket.
    drivers::WebSocketClient other(url, {{"X-Api-Key", "k2"}}, 2000ms);
    other.send("hi");
    STRCMP_EQUAL("1:hi", other.receive(2000ms).value().c_str());
    STRCMP_EQUAL("2:hi", other.receive(2000ms).value().c_str());
    server.push("news");
    STRCMP_EQUAL("news", ws.receive(2000ms).value().c_str());
    STRCMP_EQUAL("news", other.receive(2000ms).value().c_str());

    // The server closing every connection (a host restarting): the client sees it gone.
    server.drop_connections();
    CHECK_THROWS(hal::NetworkError, ws.receive(2000ms));
}

TEST(HttpDriver, a_port_nobody_listens_on_is_a_network_error) {
    // A port just freed: nothing listens there.
    int port = 0;
    {
        drivers::HttpServer s("127.0.0.1", 0, {});
        port = s.port();
    }
    const auto url = net::parse_url("http://127.0.0.1:" + std::to_string(port));
    CHECK_THROWS(hal::NetworkError, drivers::http_request(url, {}, 1000ms));
}

TEST_GROUP(KlipperConfig){};

namespace {

models::DeltaGeometry example_geometry() {
    models::DeltaGeometry g;
    g.diagonal_rod_mm = 251.0;
    g.diagonal_rod_trim_mm = {0.5, -0.25, -0.25};
    g.radius_mm = 139.2;
    g.tower_angle_trim_deg = {0.25, -0.4, 0.15};
    g.endstop_offset_mm = {0, -0.18, -0.3};
    g.height_mm = 301.7;
    return g;
}

// The SAVE_CONFIG block's lines: everything from its first "#*#".
std::string block_of(const std::string& cfg) {
    return cfg.substr(cfg.find("#*#"));
}

}  // namespace

// Hand-worked: Klipper's arm_length = rod + trim, angle = 210/330/90 + trim, position_endstop =
// height - offset (the gauge already holds: trims sum to zero, the largest offset is zero).
TEST(KlipperConfig, a_file_without_the_block_gets_one_and_keeps_its_body) {
    const std::string body =
        "[printer]\nkinematics: delta\ndelta_radius: 140\n\n[stepper_a]\narm_length: 250\n"
        "position_endstop: 300\n\n\n";
    const std::string out = models::klipper_saved_config(body, example_geometry());
    CHECK(out.rfind("[printer]\nkinematics: delta\ndelta_radius: 140\n\n[stepper_a]\narm_length: "
                    "250\nposition_endstop: 300\n\n#*# <",
                    0) == 0);
    STRCMP_EQUAL(
        "#*# <---------------------- SAVE_CONFIG ---------------------->\n"
        "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n"
        "#*#\n"
        "#*# [printer]\n#*# delta_radius = 139.200\n#*#\n"
        "#*# [stepper_a]\n#*# angle = 210.250\n#*# arm_length = 251.500\n"
        "#*# position_endstop = 301.700\n#*#\n"
        "#*# [stepper_b]\n#*# angle = 329.600\n#*# arm_length = 250.750\n"
        "#*# position_endstop = 301.880\n#*#\n"
        "#*# [stepper_c]\n#*# angle = 90.150\n#*# arm_length = 250.750\n"
        "#*# position_endstop = 302.000\n",
        block_of(out).c_str());
}

TEST(KlipperConfig, the_blocks_other_values_stay_and_its_delta_values_are_replaced) {
    const std::string before =
        "[printer]\nkinematics: delta\n\n"
        "#*# <---------------------- SAVE_CONFIG ---------------------->\n"
        "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n"
        "#*#\n#*# [bed_mesh default]\n#*# version = 1\n#*#\n"
        "#*# [stepper_a]\n#*# angle = 211.0\n#*# position_endstop = 299.0\n"
        "#*# arm_length = 249.0\n#*#\n#*# [delta_calibrate]\n#*# height0 = 1.5\n";
    const std::string out = models::klipper_saved_config(before, example_geometry());
    const std::string block = block_of(out);
    STRCMP_CONTAINS("#*# [bed_mesh default]\n#*# version = 1\n#*#\n", block.c_str());
    STRCMP_CONTAINS(
        "#*# [stepper_a]\n#*# angle = 210.250\n#*# position_endstop = 301.700\n"
        "#*# arm_length = 251.500\n",
        block.c_str());
    STRCMP_CONTAINS("#*# [delta_calibrate]\n#*# height0 = 1.5\n", block.c_str());
    CHECK(block.find("211.0") == std::string::npos);
    // Written twice, the same file: the block is read back as it was written.
    STRCMP_EQUAL(out.c_str(), models::klipper_saved_config(out, example_geometry()).c_str());
    CHECK_THROWS(std::invalid_argument,
                 models::klipper_saved_config(before + "[printer]\nx: 1\n", example_geometry()));
}

TEST(KlipperConfig, a_mismatch_names_the_first_value_that_differs_beyond_the_last_digit) {
    const auto sent = example_geometry();
    auto same = sent;
    same.radius_mm += 0.001;  // within the 3 decimals' rounding
    STRCMP_EQUAL("", models::klipper_settings_mismatch(sent, same).c_str());
    auto other = sent;
    other.diagonal_rod_trim_mm[1] += 0.01;
    other.diagonal_rod_trim_mm[2] -= 0.01;
    STRCMP_EQUAL("[stepper_b] arm_length sent 250.750, in force 250.760",
                 models::klipper_settings_mismatch(sent, other).c_str());
}

// The twin's own reading (not the box's): stepper_b and _c default to stepper_a's arm and
// endstop, the angles to 210/330/90, the SAVE_CONFIG block over the body.
TEST(KlipperConfig, the_twin_reads_printer_cfg_as_klipper_does) {
    const auto p = sim::twin_params_from_printer_cfg(
        "[printer]\nkinematics: delta\ndelta_radius: 140 # measured\n"
        "[stepper_a]\narm_length: 250\nposition_endstop: 300\n"
        "[stepper_b]\n[stepper_c]\nangle: 91\n"
        "#*# [stepper_b]\n#*# position_endstop = 299.5\n");
    DOUBLES_EQUAL(140, p.radius_mm, 1e-12);
    DOUBLES_EQUAL(250, p.diagonal_rod_mm, 1e-12);
    DOUBLES_EQUAL(299.5, p.height_mm, 1e-12);
    DOUBLES_EQUAL(-0.5, p.endstop_offset_mm[0], 1e-12);
    DOUBLES_EQUAL(0.0, p.endstop_offset_mm[1], 1e-12);
    DOUBLES_EQUAL(-0.5, p.endstop_offset_mm[2], 1e-12);
    DOUBLES_EQUAL(1.0, p.tower_angle_trim_deg[2], 1e-12);
    DOUBLES_EQUAL(0.0, p.tower_angle_trim_deg[1], 1e-12);
    try {
        sim::twin_params_from_printer_cfg("[printer]\nkinematics: delta\n[stepper_a]\n");
        FAIL("a printer.cfg without delta_radius was taken");
    } catch (const std::runtime_error& e) {
        STRCMP_CONTAINS("'delta_radius' in section 'printer' must be specified", e.what());
    }
    // The twin's printer.cfg read by the twin: the same printer.
    sim::DeltaParams q;
    q.diagonal_rod_trim_mm = {0.2, -0.1, -0.1};
    q.tower_angle_trim_deg = {0.3, 0, -0.3};
    q.endstop_offset_mm = {0, -0.4, -0.2};
    const auto r = sim::twin_params_from_printer_cfg(sim::printer_cfg_of(q, 85));
    for (std::size_t i = 0; i < 3; ++i) {
        DOUBLES_EQUAL(q.diagonal_rod_mm + q.diagonal_rod_trim_mm[i],
                      r.diagonal_rod_mm + r.diagonal_rod_trim_mm[i], 1e-9);
        DOUBLES_EQUAL(q.endstop_offset_mm[i], r.endstop_offset_mm[i], 1e-9);
        DOUBLES_EQUAL(q.tower_angle_trim_deg[i], r.tower_angle_trim_deg[i], 1e-9);
    }
}

// A cartesian printer's settings: the box's arithmetic against hand-worked values and against
// the twin's own models (Klipper's skew formula, its printer's motion), never its own output.
TEST_GROUP(KlipperSkew){};

TEST(KlipperSkew, set_skew_gives_klipper_the_lean_it_computes_back) {
    // A 100 mm square leaning 0.01: C (101, 100), D (1, 100).
    const auto lines = models::klipper_skew_commands(0.01);
    LONGS_EQUAL(2, lines.size());
    STRCMP_EQUAL("SET_SKEW XY=142.130222,140.716026,100.005000", lines[0].c_str());
    STRCMP_EQUAL("SKEW_PROFILE SAVE=calbox", lines[1].c_str());
    // Klipper's calc_skew_factor, as the twin implements it, takes the lengths back to the lean.
    for (const double lean : {-0.02, -0.0031, 0.0, 0.0047, 0.03}) {
        double l[3];
        CHECK(std::sscanf(models::klipper_skew_commands(lean)[0].c_str(), "SET_SKEW XY=%lf,%lf,%lf",
                          &l[0], &l[1], &l[2]) == 3);
        DOUBLES_EQUAL(lean, sim::twin_skew_factor(l[0], l[1], l[2]), 2e-8);
    }
}

TEST(KlipperSkew, the_corrected_settings_compose_with_those_in_force) {
    // Hand-worked: rotation distances scale by 1 + s; the lean is (skew + k0 (1 + sx)) / (1 + sy).
    const models::KlipperCartesian now{40, 40, 0.002, true};
    const auto c = models::klipper_cartesian_corrected(now, 0.01, -0.02, 0.003);
    DOUBLES_EQUAL(40.4, c.rotation_distance_x_mm, 1e-12);
    DOUBLES_EQUAL(39.2, c.rotation_distance_y_mm, 1e-12);
    DOUBLES_EQUAL((0.003 + 0.002 * 1.01) / 0.98, *c.xy_skew, 1e-15);
}

TEST(KlipperSkew, the_twin_printer_with_the_corrected_settings_is_square_and_true) {
    // The twin's printer (out of square, off in both axes) with settings already in force: its
    // linear error read off the twin as a measurement would see it, corrected, and the twin's
    // motion checked: each axis true to length, the two square.
    sim::CartesianErrors truth{0.004, -0.003, 0.3};
    const models::KlipperCartesian now{41, 39.5, 0.001, true};
    const auto firmware_of = [](const models::KlipperCartesian& k) {
        return sim::CartesianFirmware{sim::kOwnersRotationDistanceMm / k.rotation_distance_x_mm,
                                      sim::kOwnersRotationDistanceMm / k.rotation_distance_y_mm,
                                      k.xy_skew.value_or(0)};
    };
    sim::CartesianTwin before(truth, firmware_of(now));
    before.home();
    const auto x = before.actual_position_mm({100, 0, 0});
    const auto y = before.actual_position_mm({0, 100, 0});
    // e = (a x + b y, c x + d y): the twin's y axis stays on y, so c = 0 here.
    const double a = x.x / 100 - 1, b = y.x / 100, d = y.y / 100 - 1;
    DOUBLES_EQUAL(0.0, x.y, 1e-12);
    const auto corrected = models::klipper_cartesian_corrected(now, a, d, b);
    sim::CartesianTwin after(truth, firmware_of(corrected));
    after.home();
    const auto xa = after.actual_position_mm({100, 0, 0});
    const auto ya = after.actual_position_mm({0, 100, 0});
    DOUBLES_EQUAL(100, std::hypot(xa.x, xa.y), 1e-9);
    DOUBLES_EQUAL(100, std::hypot(ya.x, ya.y), 1e-9);
    DOUBLES_EQUAL(0, xa.x * ya.x + xa.y * ya.y, 1e-7);
    // Before, it was neither.
    CHECK(std::abs(std::hypot(x.x, x.y) - 100) > 0.1);
    CHECK(std::abs(x.x * y.x + x.y * y.y) > 1);
}

TEST(KlipperSkew, printer_cfg_gives_the_travel_and_the_profile_and_refuses_other_kinematics) {
    const std::string cfg =
        "[printer]\nkinematics: cartesian\n[stepper_x]\nrotation_distance: 40\n"
        "[stepper_y]\nrotation_distance: 32 ; GT2 16T\n[skew_correction]\n\n"
        "#*# <---------------------- SAVE_CONFIG ---------------------->\n"
        "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n#*#\n"
        "#*# [skew_correction calbox]\n#*# xy_skew = 0.0052\n#*# xz_skew = 0.0\n#*#\n"
        "#*# [stepper_x]\n#*# rotation_distance = 40.16\n";
    const auto k = models::read_klipper_cartesian("printer.cfg", cfg);
    DOUBLES_EQUAL(40.16, k.rotation_distance_x_mm, 1e-12);
    DOUBLES_EQUAL(32, k.rotation_distance_y_mm, 1e-12);
    CHECK(k.xy_skew.has_value());
    DOUBLES_EQUAL(0.0052, *k.xy_skew, 1e-15);
    CHECK(k.takes_skew);
    // The twin's own reader of the same file: the travel against its owner's 40 mm.
    const auto f = sim::twin_cartesian_from_printer_cfg(cfg);
    DOUBLES_EQUAL(40 / 40.16, f.travel_x, 1e-12);
    DOUBLES_EQUAL(40.0 / 32, f.travel_y, 1e-12);
    try {
        models::read_klipper_cartesian(
            "printer.cfg",
            "[printer]\nkinematics: corexy\n[stepper_x]\n"
            "rotation_distance: 40\n[stepper_y]\nrotation_distance: 40\n");
        FAIL("a corexy printer was taken as cartesian");
    } catch (const models::ImportError& e) {
        STRCMP_CONTAINS("kinematics is 'corexy', not cartesian", e.what());
    }
    // What is sent and what is in force: the first difference named.
    const models::KlipperCartesian sent{40.159141, 39.880736, 0.0052774, true};
    STRCMP_EQUAL("", models::klipper_cartesian_mismatch(sent, sent).c_str());
    auto off = sent;
    off.xy_skew = 0.00528;
    STRCMP_CONTAINS("xy_skew sent 0.005277", models::klipper_cartesian_mismatch(sent, off).c_str());
    off = sent;
    off.xy_skew.reset();
    STRCMP_CONTAINS("[skew_correction calbox] is missing",
                    models::klipper_cartesian_mismatch(sent, off).c_str());
}

TEST(KlipperSkew, only_a_file_the_box_changed_is_its_own_to_restore) {
    const std::string before =
        "# my printer\n[printer]\nkinematics: cartesian\n[stepper_x]\nrotation_distance: 40\n"
        "[stepper_y]\nrotation_distance: 40\n[skew_correction]\n";
    const std::string travel =
        models::klipper_saved_values(before, {{"stepper_x", "rotation_distance", "40.2"}});
    CHECK(models::klipper_changed_only_travel_and_skew(before, travel));
    // SAVE_CONFIG's rewrite of it: the duplicate commented out, the profile added.
    std::string saved = travel;
    saved.replace(saved.find("rotation_distance: 40"), 0, "#");
    saved += "#*#\n#*# [skew_correction calbox]\n#*# xy_skew = 0.004\n";
    CHECK(models::klipper_changed_only_travel_and_skew(before, saved));
    // Someone's edits: a comment, another setting in the block, a value above it.
    CHECK_FALSE(models::klipper_changed_only_travel_and_skew(before, "# mine\n" + saved));
    CHECK_FALSE(models::klipper_changed_only_travel_and_skew(
        before, models::klipper_saved_values(travel, {{"printer", "max_accel", "5000"}})));
    std::string edited = before;
    edited.replace(edited.find("cartesian"), 9, "corexy");
    CHECK_FALSE(models::klipper_changed_only_travel_and_skew(before, edited));
}

TEST(KlipperConfig, the_machine_files_link_says_how_the_box_reaches_the_machine) {
    const std::string base =
        "[machine]\nkind = \"delta\"\nfirmware = \"klipper\"\n[delta]\ndiagonal_rod_mm = 250\n"
        "radius_mm = 140\nheight_mm = 300\n";
    const auto m = models::parse_machine_file(
        base +
            "[link]\nkind = \"moonraker\"\nurl = \"http://p:7125\"\nkey_file = \"/k\"\n"
            "reply_timeout_s = 5\n",
        "m.toml");
    STRCMP_EQUAL("moonraker", m.link.kind.c_str());
    STRCMP_EQUAL("http://p:7125", m.link.url.c_str());
    DOUBLES_EQUAL(5, m.link.reply_timeout_s, 0);
    CHECK_FALSE(models::parse_machine_file(base, "m.toml").link.is_host());
    CHECK_THROWS(models::MachineFileError,
                 models::parse_machine_file(base + "[link]\nurl = \"http://p\"\n", "m.toml"));
    CHECK_THROWS(models::MachineFileError,
                 models::parse_machine_file(base + "[link]\nkind = \"telnet\"\n", "m.toml"));
    std::string marlin = base;
    marlin.replace(marlin.find("klipper"), 7, "marlin");
    try {
        models::parse_machine_file(marlin + "[link]\nkind = \"moonraker\"\n", "m.toml");
        FAIL("Moonraker in front of Marlin was taken");
    } catch (const models::MachineFileError& e) {
        STRCMP_CONTAINS("Klipper", e.what());
    }
}

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
