// The Raspberry Pi board's file: the shipped board/rpi/board.toml says what the defaults are,
// a file overrides them key by key, and a typo is an error naming the file and the key.
#include <CppUTest/TestHarness.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "board/rpi/rpi_board.hpp"

using namespace calbox;

namespace {

std::string written(const std::string& name, const std::string& text) {
    const std::string path = "/tmp/calbox-test-" + std::to_string(::getpid()) + "-" + name;
    std::ofstream(path) << text;
    return path;
}

std::string refusal(const std::string& path) {
    try {
        board::read_rpi_settings(path);
    } catch (const std::runtime_error& e) {
        std::remove(path.c_str());
        return e.what();
    }
    std::remove(path.c_str());
    return "read";
}

}  // namespace

TEST_GROUP(RpiBoard){};

TEST(RpiBoard, the_shipped_board_file_says_the_defaults) {
    const auto shipped = board::read_rpi_settings(CALBOX_SOURCE_DIR "/board/rpi/board.toml");
    const auto defaults = board::default_rpi_settings();
    STRCMP_EQUAL(defaults.camera_v4l2_device.c_str(), shipped.camera_v4l2_device.c_str());
    CHECK_EQUAL(defaults.camera_width_px, shipped.camera_width_px);
    CHECK_EQUAL(defaults.camera_height_px, shipped.camera_height_px);
    STRCMP_EQUAL("GPIO17", shipped.lines.button.name.c_str());
    STRCMP_EQUAL(defaults.lines.led_ready.name.c_str(), shipped.lines.led_ready.name.c_str());
    STRCMP_EQUAL(defaults.lines.led_busy.name.c_str(), shipped.lines.led_busy.name.c_str());
    STRCMP_EQUAL(defaults.lines.led_error.name.c_str(), shipped.lines.led_error.name.c_str());
    STRCMP_EQUAL(defaults.lines.light.name.c_str(), shipped.lines.light.name.c_str());
    STRCMP_EQUAL(defaults.display_i2c_bus.c_str(), shipped.display_i2c_bus.c_str());
    CHECK_EQUAL(0x3c, shipped.display_address);
    CHECK(shipped.display_controller == defaults.display_controller);
    STRCMP_EQUAL(defaults.console_device.c_str(), shipped.console_device.c_str());
    STRCMP_EQUAL(defaults.machine_device.c_str(), shipped.machine_device.c_str());
    CHECK_EQUAL(defaults.machine_baud, shipped.machine_baud);
}

TEST(RpiBoard, a_board_file_overrides_key_by_key_and_a_typo_is_named) {
    const auto path = written("board.toml",
                              "[lines]\nbutton = \"START\"\n[display]\ncontroller = \"sh1106\"\n"
                              "address = 0x3d\n[machine]\ndevice = \"/dev/serial/by-id/usb-x\"\n"
                              "baud = 250000\n");
    const auto s = board::read_rpi_settings(path);
    std::remove(path.c_str());
    STRCMP_EQUAL("START", s.lines.button.name.c_str());
    STRCMP_EQUAL("GPIO22", s.lines.led_ready.name.c_str());  // not given: the default
    CHECK(s.display_controller == drivers::OledController::sh1106);
    CHECK_EQUAL(0x3d, s.display_address);
    STRCMP_EQUAL("/dev/serial/by-id/usb-x", s.machine_device.c_str());
    CHECK_EQUAL(250000, s.machine_baud);

    STRCMP_CONTAINS("[display] controller",
                    refusal(written("c.toml", "[display]\ncontroller = \"ssd1309\"\n")).c_str());
    STRCMP_CONTAINS("unknown section [camra]",
                    refusal(written("s.toml", "[camra]\nwidth_px = 5\n")).c_str());
    STRCMP_CONTAINS("[display] address",
                    refusal(written("a.toml", "[display]\naddress = 0x80\n")).c_str());
    STRCMP_CONTAINS("cannot read the board file",
                    refusal("/tmp/calbox-no-such-board.toml").c_str());
}
