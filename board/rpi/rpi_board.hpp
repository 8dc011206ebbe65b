#pragma once
// The Raspberry Pi board (Pi 4 and Pi 5): where its devices are (board/rpi/board.toml) and the
// drivers that open them. Opening stops at the first device that is not there, naming it.
#include <memory>
#include <string>

#include "board/devices.hpp"
#include "drivers/gpio_lines.hpp"
#include "drivers/oled_display.hpp"
#include "drivers/v4l2_camera.hpp"
#include "hal/camera.hpp"
#include "hal/clock.hpp"
#include "hal/display.hpp"
#include "hal/lines.hpp"
#include "hal/serial_port.hpp"

namespace calbox::board {

struct RpiSettings {
    std::string camera_v4l2_device = "/dev/video0";
    int camera_width_px = 4056, camera_height_px = 3040;
    drivers::GpioLinesSettings lines;  // names GPIO17 (button), 22 23 24 (LEDs), 27 (light)
    std::string display_i2c_bus = "/dev/i2c-1";
    int display_address = 0x3c;
    drivers::OledController display_controller = drivers::OledController::ssd1306;
    std::string console_device = "/dev/serial0";  // the appliance's default console
    std::string machine_device = "/dev/ttyACM0";
    int machine_baud = 115200;
};

RpiSettings default_rpi_settings();

// Reads a board file over the defaults. Throws std::runtime_error naming the file and the key
// at fault (unknown keys and sections included).
RpiSettings read_rpi_settings(const std::string& path);

// Opens the camera, the GPIO lines, the display and the machine's port, in that order (the
// console is the appliance's to open: a USB adapter may come and go). Throws
// std::runtime_error with one line: "the camera: ...", "the button and lights: ...", naming
// what it looked for and why it is not usable. `clock` must be CLOCK_MONOTONIC's.
Devices open_rpi_devices(const RpiSettings& settings, hal::Clock& clock);

}  // namespace calbox::board
