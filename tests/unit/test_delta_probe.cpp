// The printer's own probe over the machine link (issue "Delta mode 3"): where the box probes,
// the job for each firmware, the reports read back (as Marlin and RepRapFirmware print them, and
// as the twin answers), the probe file `calbox solve delta --probe` takes, and [probe].
#include <CppUTest/TestHarness.h>

#include <cmath>
#include <string>

#include "board/sim/machine_twin.hpp"
#include "core/models/machine_file.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/modes/record_error.hpp"
#include "tests/support/twin_fixtures.hpp"

using namespace calbox;

TEST_GROUP(DeltaProbe){};

TEST(DeltaProbe, the_points_are_the_centre_and_two_rings_with_tower_a_on_each) {
    const auto points = modes::probe_points({60.0, 0.01});
    CHECK_EQUAL(19u, points.size());
    DOUBLES_EQUAL(0, std::hypot(points[0].x, points[0].y), 0);
    // Tower A stands at 210 degrees: (-cos 30, -sin 30) times the radius.
    DOUBLES_EQUAL(-30 * std::sqrt(3.0) / 2, points[1].x, 1e-9);
    DOUBLES_EQUAL(-15, points[1].y, 1e-9);
    DOUBLES_EQUAL(-30 * std::sqrt(3.0), points[7].x, 1e-9);
    DOUBLES_EQUAL(-30, points[7].y, 1e-9);
    for (std::size_t i = 7; i < points.size(); ++i)
        DOUBLES_EQUAL(60, std::hypot(points[i].x, points[i].y), 1e-9);
}

TEST(DeltaProbe, each_firmware_gets_its_own_probing_command_between_homings) {
    const std::vector<geometry::Point2> points{{0, 0}, {-51.96, -30}};
    const auto marlin = modes::probe_job("marlin", points);
    CHECK_EQUAL(4u, marlin.size());
    STRCMP_EQUAL("G28", marlin[0].c_str());
    STRCMP_EQUAL("G30 X0.00 Y0.00", marlin[1].c_str());
    STRCMP_EQUAL("G30 X-51.96 Y-30.00", marlin[2].c_str());
    STRCMP_EQUAL("G28", marlin[3].c_str());
    const auto rrf = modes::probe_job("rrf", points);
    CHECK_EQUAL(6u, rrf.size());
    STRCMP_EQUAL("G1 X-51.96 Y-30.00 Z5 F6000", rrf[3].c_str());
    STRCMP_EQUAL("G30 S-1", rrf[4].c_str());
    const auto klipper = modes::probe_job("klipper", points);
    CHECK_EQUAL(6u, klipper.size());
    STRCMP_EQUAL("G1 X-51.96 Y-30.00 Z5 F6000", klipper[3].c_str());
    STRCMP_EQUAL("PROBE", klipper[4].c_str());
    STRCMP_EQUAL("G28", klipper[5].c_str());
}

// Klipper's PROBE says where the toolhead was when the probe triggered, its z_offset above the
// bed: a trigger at z=1.650 with z_offset 1.350 is a bed 0.30 mm high, a gap of -0.30.
TEST(DeltaProbe, klipper_reports_take_the_probes_z_offset_off) {
    const std::vector<geometry::Point2> points{{0, 0}, {10, -20}};
    const auto probe = modes::probe_from_replies(
        "klipper", points,
        {"// probe at 0.000,0.000 is z=1.650000", "ok", "// probe at 10.000,-20.000 is z=1.250000"},
        0.01, 1.35);
    CHECK_EQUAL(2u, probe.size());
    DOUBLES_EQUAL(-0.30, probe[0].z_mm, 1e-12);
    DOUBLES_EQUAL(0.10, probe[1].z_mm, 1e-12);
    DOUBLES_EQUAL(-20, probe[1].y_mm, 0);
    CHECK_THROWS(std::invalid_argument,
                 modes::probe_from_replies("klipper", points,
                                           {"// probe at 0.000,0.000 is z=1.650000",
                                            "// probe at 30.000,-20.000 is z=1.250000"},
                                           0.01, 1.35));
    try {
        modes::probe_from_replies("klipper", points, {}, 0.01);
        FAIL("Klipper's reports were read without the probe's z_offset");
    } catch (const std::invalid_argument& e) {
        STRCMP_CONTAINS("z_offset", e.what());
    }
}

TEST(DeltaProbe, marlin_reports_are_read_with_their_points_and_the_height_negated) {
    const std::vector<geometry::Point2> points{{0, 0}, {10, -20}};
    // As a host sees them: echoes and "ok" between the reports.
    const auto probe =
        modes::probe_from_replies("marlin", points,
                                  {"echo:busy: processing", "Bed X: 0.00 Y: 0.00 Z: 0.35", "ok",
                                   "Bed X: 10.00 Y: -20.00 Z: -0.12", "ok"},
                                  0.02);
    CHECK_EQUAL(2u, probe.size());
    DOUBLES_EQUAL(-0.35, probe[0].z_mm, 1e-12);  // the bed 0.35 mm up: the nozzle into it
    DOUBLES_EQUAL(0.12, probe[1].z_mm, 1e-12);
    DOUBLES_EQUAL(-20, probe[1].y_mm, 0);
    DOUBLES_EQUAL(0.02, probe[1].sigma_mm, 0);
    // One report short, or a report from somewhere else, is refused.
    try {
        modes::probe_from_replies("marlin", points, {"Bed X: 0.00 Y: 0.00 Z: 0.35"}, 0.01);
        FAIL("accepted one report for two points");
    } catch (const std::invalid_argument& e) {
        STRCMP_EQUAL("the printer reported 1 probe height(s) for 2 points", e.what());
    }
    try {
        modes::probe_from_replies("marlin", points,
                                  {"Bed X: 0.00 Y: 0.00 Z: 0.35", "Bed X: 30.00 Y: -20.00 Z: 0.1"},
                                  0.01);
        FAIL("accepted a point reported elsewhere");
    } catch (const std::invalid_argument& e) {
        STRCMP_EQUAL(
            "probe point 2 was reported at (30.00, -20.00) where the box asked for (10.00, -20.00)",
            e.what());
    }
    CHECK_THROWS(std::invalid_argument,
                 modes::probe_from_replies("marlin", {{0, 0}}, {"Bed X: 0.00 Y: 0.00"}, 0.01));
}

TEST(DeltaProbe, reprap_reports_are_paired_with_the_points_in_order) {
    const std::vector<geometry::Point2> points{{0, 0}, {10, -20}};
    const auto probe = modes::probe_from_replies(
        "rrf", points, {"Stopped at height 0.021 mm", "ok", "Stopped at height -0.250 mm"}, 0.01);
    DOUBLES_EQUAL(-0.021, probe[0].z_mm, 1e-12);
    DOUBLES_EQUAL(0.25, probe[1].z_mm, 1e-12);
    DOUBLES_EQUAL(10, probe[1].x_mm, 0);
    CHECK_THROWS(std::invalid_argument,
                 modes::probe_from_replies("rrf", points, {"Stopped at height 0.021 mm"}, 0.01));
}

TEST(DeltaProbe, a_probe_file_is_csv_rows_or_a_marlin_console_log) {
    const auto csv = modes::probe_from_file("x,y,z\n# probed\n1,2,0.05\n-3.5,4,-0.1\n", "p.csv");
    CHECK_EQUAL(2u, csv.size());
    DOUBLES_EQUAL(-0.1, csv[1].z_mm, 0);  // rows are the gap as they stand
    const auto log = modes::probe_from_file(
        "Send: G29 V3\nRecv: Bed X: -40.000 Y: 20.000 Z: 0.250\nRecv: echo:busy\n"
        "Recv: Bed x: 10 y: 140.00 z: -0.11\nRecv: ok\n",
        "g29.log");
    CHECK_EQUAL(2u, log.size());
    DOUBLES_EQUAL(-0.25, log[0].z_mm, 1e-12);
    DOUBLES_EQUAL(140, log[1].y_mm, 0);
    DOUBLES_EQUAL(0.11, log[1].z_mm, 1e-12);
    try {
        modes::probe_from_file("1,2,0.05\n1;2;3\n", "p.csv");
        FAIL("accepted a row that is not x,y,z");
    } catch (const modes::RecordError& e) {
        STRCMP_EQUAL("p.csv:2: expected x,y,z (or a Marlin log's \"Bed X:\" lines)", e.what());
    }
    try {
        modes::probe_from_file("Bed X: 1.00 Y: 2.00 Z: 0.1\nBed X: 1.00 Y: 2.00\n", "g30.log");
        FAIL("accepted a report line without its height");
    } catch (const modes::RecordError& e) {
        STRCMP_CONTAINS("g30.log:2: a probe report line without its X, Y and Z", e.what());
    }
    CHECK_THROWS(modes::RecordError, modes::probe_from_file("# nothing\n", "empty.csv"));
    // What the box keeps in a cycle's record reads back as it was, to the digits it writes.
    const auto back = modes::probe_from_file(modes::probe_to_csv(log), "probe.csv");
    CHECK_EQUAL(2u, back.size());
    DOUBLES_EQUAL(-40, back[0].x_mm, 5e-4);
    DOUBLES_EQUAL(-0.25, back[0].z_mm, 5e-5);
    DOUBLES_EQUAL(0.11, back[1].z_mm, 5e-5);
}

TEST(DeltaProbe, the_twin_answers_g30_with_the_gap_a_hand_worked_height_error_gives) {
    // Firmware that believes the printer 0.3 mm shorter than it is: at commanded Z = 0 the
    // nozzle stands 0.3 mm over the bed everywhere, so the bed reads at Z = -0.30.
    sim::DeltaParams truth;
    sim::DeltaParams firmware = truth;
    firmware.height_mm = truth.height_mm - 0.3;
    const std::vector<geometry::Point2> points{{0, 0}, {-51.96, -30}, {0, 60}};
    for (const auto dialect : {sim::DeltaDialect::marlin, sim::DeltaDialect::rrf}) {
        sim::DeltaTwin twin(truth, firmware, dialect);
        const std::string name = dialect == sim::DeltaDialect::marlin ? "marlin" : "rrf";
        const auto probe = modes::probe_from_replies(
            name, points, test::replies_of_twin(twin, modes::probe_job(name, points)), 0.01);
        for (const auto& p : probe) DOUBLES_EQUAL(0.3, p.z_mm, 0.02);  // 0.004 noise, 0.01 print
    }
    // Klipper's twin answers PROBE (its host's G30) with the trigger's height, its z_offset up.
    sim::DeltaTwin klipper(truth, firmware, sim::DeltaDialect::klipper);
    klipper.set_klipper_probe_z_offset(1.35);
    auto job = modes::probe_job("klipper", points);
    for (auto& line : job)
        if (line == "PROBE") line = "G30";
    const auto probe = modes::probe_from_replies("klipper", points,
                                                 test::replies_of_twin(klipper, job), 0.01, 1.35);
    for (const auto& p : probe) DOUBLES_EQUAL(0.3, p.z_mm, 0.02);
    // A machine without a probe says so.
    sim::CartesianTwin cartesian({});
    try {
        test::replies_of_twin(cartesian, {"G28", "G30 X0 Y0"});
        FAIL("a cartesian twin probed");
    } catch (const sim::JobError& e) {
        STRCMP_EQUAL("line 2: G30: this machine has no bed probe", e.what());
    }
}

TEST(DeltaProbe, the_machine_file_takes_a_probe_for_marlin_and_reprap_within_the_bed) {
    const std::string base = test::kDeltaMachineToml;
    const auto m = models::parse_machine_file(base + "[probe]\nradius_mm = 70\n", "p.toml");
    CHECK(m.probe.has_value());
    DOUBLES_EQUAL(70, m.probe->radius_mm, 0);
    DOUBLES_EQUAL(0.01, m.probe->repeatability_mm, 0);
    // The probe changes how the printer is measured, not what it is: measurements stay valid.
    STRCMP_EQUAL(models::fingerprint(models::parse_machine_file(base, "p.toml")).c_str(),
                 models::fingerprint(m).c_str());
    try {
        models::parse_machine_file(base + "[probe]\nradius_mm = 90\n", "p.toml");
        FAIL("accepted a probe beyond the bed");
    } catch (const models::MachineFileError& e) {
        STRCMP_CONTAINS("radius_mm", e.what());
        STRCMP_CONTAINS("beyond the bed", e.what());
    }
    CHECK_THROWS(models::MachineFileError,
                 models::parse_machine_file(base + "[probe]\nrepeatability_mm = 0.01\n", "p"));
    std::string klipper = base;
    klipper.replace(klipper.find("kind = \"delta\""), 14,
                    "kind = \"delta\"\nfirmware = \"klipper\"");
    try {
        models::parse_machine_file(klipper + "[probe]\nradius_mm = 70\n", "k.toml");
        FAIL("accepted a probe read from Klipper over a serial port");
    } catch (const models::MachineFileError& e) {
        STRCMP_CONTAINS("[probe] on Klipper is read through Moonraker", e.what());
    }
    // Through Moonraker, which gives the probe's z_offset with the settings in force.
    const auto through_host = models::parse_machine_file(
        klipper +
            "[link]\nkind = \"moonraker\"\nurl = \"http://p:7125\"\n[probe]\nradius_mm = 70\n",
        "k.toml");
    CHECK(through_host.probe.has_value());
}
