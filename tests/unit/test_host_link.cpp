// A printer behind a host: the HTTP and WebSocket driver on loopback, printer.cfg's SAVE_CONFIG
// block as the box writes it, the twin's own reading of printer.cfg, and the Moonraker link
// against the twin's host (faults included).
#include "tests/unit/host_link_rig.hpp"

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
    saved.insert(saved.find("rotation_distance: 40"), 1, '#');
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
