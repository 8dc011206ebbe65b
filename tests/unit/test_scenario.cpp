#include <CppUTest/TestHarness.h>
#include <unistd.h>

#include <fstream>
#include <iterator>

#include "board/sim/scenario.hpp"
#include "board/sim/sim_board.hpp"
#include "board/sim/twin_kind.hpp"
#include "core/models/machine_file.hpp"
#include "core/models/machine_kinds.hpp"

using namespace calbox::sim;

namespace {
std::string write_temp(const std::string& text) {
    char name[] = "/tmp/calbox-scenario-XXXXXX";
    const int fd = ::mkstemp(name);
    if (fd < 0) FAIL("mkstemp failed");
    ::close(fd);
    std::ofstream(name) << text;
    return name;
}

const char* kDelta =
    "[machine]\nkind = \"delta\"\n[delta]\ndiagonal_rod_mm = 250.0\nradius_mm = 140.0\n";

std::string error_of(const std::string& text) {
    const auto path = write_temp(text);
    try {
        load_scenario(path);
    } catch (const ScenarioError& e) {
        ::unlink(path.c_str());
        return e.what();
    }
    ::unlink(path.c_str());
    return "";
}
}  // namespace

TEST_GROUP(Scenario){};

TEST(Scenario, truth_defaults_to_the_firmware_belief_key_by_key) {
    const auto path = write_temp(std::string(kDelta) +
                                 "[truth.delta]\ndiagonal_rod_mm = 251.5\n"
                                 "[camera]\nwidth_px = 800\nheight_px = 600\nfx = 900\n"
                                 "distortion = [-0.1, 0.01]\nposition_mm = [0, -30, 400]\n");
    const Scenario s = load_scenario(path);
    ::unlink(path.c_str());
    DOUBLES_EQUAL(251.5, s.delta_truth.diagonal_rod_mm, 0);
    DOUBLES_EQUAL(250.0, s.delta_firmware.diagonal_rod_mm, 0);
    DOUBLES_EQUAL(140.0, s.delta_truth.radius_mm, 0);
    CHECK(s.camera.has_value());
    DOUBLES_EQUAL(399.5, s.camera->intrinsics.cx, 0);  // centre of an 800 px row
    DOUBLES_EQUAL(900, s.camera->intrinsics.fy, 0);    // fy defaults to fx
    CHECK_EQUAL(2u, s.camera->intrinsics.distortion.size());
}

TEST(Scenario, bad_files_name_the_file_and_the_key) {
    STRCMP_CONTAINS("missing [machine]", error_of("[delta]\nradius_mm = 1\n").c_str());
    STRCMP_CONTAINS("[machine] kind: 'scara' is not one of",
                    error_of("[machine]\nkind = \"scara\"\n").c_str());
    STRCMP_CONTAINS("[delta] radus_mm: unknown key",
                    error_of(std::string(kDelta) + "radus_mm = 3\n").c_str());
    STRCMP_CONTAINS(
        "radius_mm: must be a number",
        error_of("[machine]\nkind = \"delta\"\n[delta]\nradius_mm = \"big\"\n").c_str());
    STRCMP_CONTAINS(
        "diagonal_rod_mm: must exceed radius_mm",
        error_of("[machine]\nkind = \"delta\"\n[delta]\ndiagonal_rod_mm = 100\nradius_mm = 140\n")
            .c_str());
    STRCMP_CONTAINS("endstop_offset_mm",
                    error_of(std::string(kDelta) + "endstop_offset_mm = [0.1, 0, 0]\n").c_str());
    STRCMP_CONTAINS("needs 3 numbers",
                    error_of(std::string(kDelta) + "tower_angle_trim_deg = [0, 0]\n").c_str());
    STRCMP_CONTAINS("unknown section or key 'cameras'",
                    error_of(std::string(kDelta) + "[cameras]\n").c_str());
    STRCMP_CONTAINS("a delta machine needs [delta]",
                    error_of("[machine]\nkind = \"delta\"\n").c_str());
    STRCMP_CONTAINS(
        "[setup] reference_marks_at_mm: x, y pairs",
        error_of(std::string(kDelta) + "[setup]\nreference_marks_at_mm = [1, 2, 3]\n").c_str());
    STRCMP_CONTAINS(
        "[setup] reference_dictionary: unknown ArUco dictionary 'DICT_9X9'",
        error_of(std::string(kDelta) + "[setup]\nreference_dictionary = \"DICT_9X9\"\n").c_str());
    // A TOML syntax error reports its line.
    STRCMP_CONTAINS(":2:", error_of("[machine]\nkind = = 3\n").c_str());
}

TEST(Scenario, a_missing_file_is_an_error) {
    CHECK_THROWS(ScenarioError, load_scenario("/nonexistent/scenario.toml"));
}

TEST(Scenario, the_bed_carries_the_print_as_it_cools_and_the_box_takes_it_out) {
    // Aluminium (23.1e-6 per K) printed on at 60 C, photographed at 25 C: by hand,
    // 1 - 23.1e-6 * 35 = 0.9991915, so a point laid 80 mm from the centre is seen 0.0647 mm inward.
    const auto path = write_temp(
        "[machine]\nkind = \"delta\"\nbed_material = \"aluminium\"\nbed_temperature_c = 60.0\n"
        "[delta]\n[photo]\nbed_temperature_c = 25.0\n");
    const Scenario s = load_scenario(path);
    ::unlink(path.c_str());
    DOUBLES_EQUAL(0.9991915, bed_growth_at_photo(s), 1e-12);
    const auto seen = carried_by_bed({{{80, 0, 0.2}, {80, 10, 0.2}, 0.45}}, bed_growth_at_photo(s));
    DOUBLES_EQUAL(80 - 0.064680, seen[0].a_mm.x, 1e-6);
    DOUBLES_EQUAL(0.2, seen[0].a_mm.z, 0);  // the plate grows in its plane
    // The box's own correction (core) undoes the twin's growth.
    DOUBLES_EQUAL(bed_growth_at_photo(s), calbox::models::bed_scale_at_photo(s.machine, 25.0),
                  1e-15);
    DOUBLES_EQUAL(1.0, calbox::models::bed_scale_at_photo(s.machine, std::nullopt), 0);
    // The machine file's photo temperature is the default; a reading given overrides it.
    auto cooling = s.machine;
    cooling.photo_bed_temperature_c = 25.0;
    DOUBLES_EQUAL(bed_growth_at_photo(s), calbox::models::bed_scale_at_photo(cooling, std::nullopt),
                  1e-15);
    DOUBLES_EQUAL(1.0, calbox::models::bed_scale_at_photo(cooling, 60.0), 0);
    // Glass barely moves: 3.3e-6 * -35.
    auto glass = s.machine;
    glass.bed_material = "glass";
    DOUBLES_EQUAL(1 - 3.3e-6 * 35, calbox::models::bed_scale_at_photo(glass, 25.0), 1e-15);
    // A photo temperature without the bed's material cannot be corrected: said, not guessed.
    STRCMP_CONTAINS("needs the bed's material",
                    error_of("[machine]\nkind = \"delta\"\n[delta]\n[photo]\n"
                             "bed_temperature_c = 25.0\n")
                        .c_str());
    STRCMP_CONTAINS("photo_bed_temperature_c needs bed_material and bed_temperature_c",
                    error_of("[machine]\nkind = \"delta\"\nphoto_bed_temperature_c = 30.0\n"
                             "[delta]\n")
                        .c_str());
    auto bare = s.machine;
    bare.bed_material.reset();
    CHECK_THROWS(calbox::models::MachineFileError, calbox::models::bed_scale_at_photo(bare, 25.0));
}

// The twin's bench refuses reference marks a photo could not show whole: under the plane's board
// (the marks' view is taken from the plane's photo) or partly out of the camera's view.
TEST(Scenario, reference_marks_under_the_board_or_out_of_view_are_refused) {
    std::ifstream in(std::string(CALBOX_SOURCE_DIR) + "/tests/scenarios/delta_cycle_small.toml");
    const std::string base((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto bench_error = [&](const std::string& marks) {
        const auto path = write_temp(base + "\n[setup]\nreference_marks_at_mm = " + marks + "\n");
        std::string error;
        try {
            TwinBench bench(load_scenario(path));
        } catch (const ScenarioError& e) {
            error = e.what();
        }
        ::unlink(path.c_str());
        return error;
    };
    STRCMP_EQUAL("", bench_error("[-132.0, 0.0, 132.0, 0.0]").c_str());
    // The 9x6 board of 20 mm squares, its first corner at (-80, 50): paper over x -120..120, y
    // -90..90.
    STRCMP_CONTAINS("reference mark 1 lies under the plane's board",
                    bench_error("[-132.0, 0.0, 0.0, 0.0]").c_str());
    STRCMP_CONTAINS("reference mark 0 is not wholly in the camera's view",
                    bench_error("[-150.0, 0.0]").c_str());
}

// The machine kinds, declared once (core/models/machine_kinds.hpp): the machine file's reader
// takes every kind and its answers from the table, the twin has one for each, and each names a
// page that exists. (A twin missing for a kind fails the build: twin_kind.cpp's static_assert;
// a family without its mode, make_mode.cpp's switch.)
TEST_GROUP(MachineKinds){};

TEST(MachineKinds, every_kind_is_read_from_the_machine_file_with_its_twin_and_its_page) {
    namespace models = calbox::models;
    for (const auto& k : models::kMachineKinds) {
        const std::string kind(k.name);
        const bool delta = k.family == models::MachineFamily::delta;
        const std::string text =
            "[machine]\nkind = \"" + kind + "\"\n" +
            (delta ? "[delta]\ndiagonal_rod_mm = 250.0\nradius_mm = 140.0\n" : "");
        const auto m = models::parse_machine_file(text, "m.toml");
        STRCMP_EQUAL(kind.c_str(), m.kind.c_str());
        CHECK_TEXT(m.family() == k.family, kind.c_str());
        CHECK_EQUAL(k.printer, m.is_printer());
        CHECK_EQUAL(k.jobs_at_work_zero, m.jobs_at_work_zero());
        CHECK_EQUAL(delta, m.delta.has_value());
        CHECK_EQUAL(k.family == models::MachineFamily::galvo, m.galvo.has_value());
        CHECK_EQUAL(k.family == models::MachineFamily::planar, m.planar.has_value());
        if (m.planar) STRCMP_EQUAL(std::string(k.planar_holes).c_str(), m.planar->holes.c_str());
        const std::string truth = twin_kind_of(m).truth_table();
        CHECK_TEXT(truth_table_names().contains(truth), kind.c_str());
        const std::string page = std::string(CALBOX_SOURCE_DIR) + "/" + std::string(k.docs);
        CHECK_TEXT(::access(page.c_str(), R_OK) == 0, page.c_str());
    }
    STRCMP_EQUAL("delta|cartesian|router|laser|galvo", models::machine_kind_list("|").c_str());
    STRCMP_EQUAL("cartesian 3D printers, CNC routers and gantry lasers",
                 models::family_machines(models::MachineFamily::planar).c_str());
    STRCMP_EQUAL("delta 3D printers",
                 models::family_machines(models::MachineFamily::delta).c_str());
}

TEST(MachineKinds, a_kind_the_table_does_not_hold_is_refused_never_taken_for_another) {
    namespace models = calbox::models;
    try {
        models::parse_machine_file("[machine]\nkind = \"corexy\"\n", "m.toml");
        FAIL("kind = corexy was read");
    } catch (const models::MachineFileError& e) {
        STRCMP_CONTAINS("'corexy' is not one of cartesian, delta, galvo, laser, router", e.what());
    }
    models::MachineFile m;
    m.kind = "corexy";
    CHECK_THROWS(std::invalid_argument, m.is_planar());
    CHECK_THROWS(std::invalid_argument, m.is_printer());
}
