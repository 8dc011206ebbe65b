#include "board/rpi/rpi_board.hpp"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/models/toml_reader.hpp"
#include "drivers/libcamera_camera.hpp"
#include "drivers/termios_port.hpp"

namespace calbox::board {
namespace {

drivers::GpioLineAddress line_named(const std::string& name) {
    drivers::GpioLineAddress a;
    a.name = name;
    return a;
}

// Runs `open`, prefixing what it throws with the device's part in the box.
template <class Open>
auto opening(const char* part, Open&& open) {
    try {
        return open();
    } catch (const std::exception& e) {
        throw std::runtime_error(std::string(part) + ": " + e.what());
    }
}

}  // namespace

RpiSettings default_rpi_settings() {
    RpiSettings s;
    s.lines.button = line_named("GPIO17");
    s.lines.led_ready = line_named("GPIO22");
    s.lines.led_busy = line_named("GPIO23");
    s.lines.led_error = line_named("GPIO24");
    s.lines.light = line_named("GPIO27");
    return s;
}

RpiSettings read_rpi_settings(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot read the board file");
    std::stringstream text;
    text << in.rdbuf();
    const toml::table root = models::parse_toml(text.str(), path);
    for (const auto& [key, value] : root) {
        const std::string k(key.str());
        if (k != "camera" && k != "lines" && k != "display" && k != "console" && k != "machine") {
            std::string why = path;
            why.append(": unknown section [").append(k).append("]");
            throw std::runtime_error(why);
        }
    }
    RpiSettings s = default_rpi_settings();
    if (const auto* t = models::subtable(path, root, "camera")) {
        models::TomlReader r(path, *t, "camera");
        std::optional<std::string> device;
        r.text("v4l2_device", device);
        if (device) s.camera_v4l2_device = *device;
        r.integer("width_px", s.camera_width_px, 16, 20000);
        r.integer("height_px", s.camera_height_px, 16, 20000);
        r.finish();
    }
    if (const auto* t = models::subtable(path, root, "lines")) {
        models::TomlReader r(path, *t, "lines");
        const auto name = [&](const char* key, drivers::GpioLineAddress& field) {
            std::optional<std::string> v;
            r.text(key, v);
            if (v) field = line_named(*v);
        };
        name("button", s.lines.button);
        name("led_ready", s.lines.led_ready);
        name("led_busy", s.lines.led_busy);
        name("led_error", s.lines.led_error);
        name("light", s.lines.light);
        r.finish();
    }
    if (const auto* t = models::subtable(path, root, "display")) {
        models::TomlReader r(path, *t, "display");
        std::optional<std::string> bus;
        r.text("i2c_bus", bus);
        if (bus) s.display_i2c_bus = *bus;
        r.integer("address", s.display_address, 0x03, 0x77);
        std::string controller = "ssd1306";
        r.text("controller", controller, {"ssd1306", "sh1106"});
        s.display_controller = controller == "sh1106" ? drivers::OledController::sh1106
                                                      : drivers::OledController::ssd1306;
        r.finish();
    }
    const auto port = [&](const char* section, std::string& device, int& baud) {
        if (const auto* t = models::subtable(path, root, section)) {
            models::TomlReader r(path, *t, section);
            std::optional<std::string> d;
            r.text("device", d);
            if (d) device = *d;
            r.integer("baud", baud, 1200, 4000000);
            r.finish();
        }
    };
    if (const auto* t = models::subtable(path, root, "console")) {
        models::TomlReader r(path, *t, "console");
        std::optional<std::string> d;
        r.text("device", d);
        if (d) s.console_device = *d;
        r.finish();
    }
    port("machine", s.machine_device, s.machine_baud);
    return s;
}

Devices open_rpi_devices(const RpiSettings& settings, hal::Clock& clock) {
    Devices d;
    // libcamera first (the Pi's cameras); a USB camera through V4L2 when libcamera has none.
    d.camera = opening("the camera", [&]() -> std::unique_ptr<hal::Camera> {
        std::string libcamera_failed;
        try {
            return drivers::open_libcamera_camera(
                {settings.camera_width_px, settings.camera_height_px, 2});
        } catch (const std::runtime_error& e) {
            libcamera_failed = e.what();
        }
        try {
            drivers::V4l2Settings v;
            v.width_px = settings.camera_width_px;
            v.height_px = settings.camera_height_px;
            return std::make_unique<drivers::V4l2Camera>(
                drivers::open_v4l2_device(settings.camera_v4l2_device), v);
        } catch (const std::runtime_error& e) {
            throw std::runtime_error(libcamera_failed + ", and " + e.what());
        }
    });
    d.lines = opening("the button and lights", [&]() -> std::unique_ptr<hal::Lines> {
        return std::make_unique<drivers::GpioLines>(drivers::make_libgpiod_chipset(),
                                                    settings.lines, clock);
    });
    d.display = opening("the display", [&]() -> std::unique_ptr<hal::Display> {
        return std::make_unique<drivers::OledDisplay>(
            std::make_unique<drivers::I2cDevBus>(settings.display_i2c_bus,
                                                 settings.display_address),
            settings.display_controller);
    });
    d.machine = opening("the machine's port", [&]() -> std::unique_ptr<hal::SerialPort> {
        return std::make_unique<drivers::TermiosPort>(settings.machine_device,
                                                      settings.machine_baud);
    });
    d.network = network();
    return d;
}

}  // namespace calbox::board
