#pragma once
// SSD1306 and SH1106 128x64 OLED panels on an I2C bus (i2c-dev).
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "hal/display.hpp"

namespace calbox::drivers {

// One I2C write transaction per call: the control byte, then the payload.
class ByteBus {
  public:
    virtual ~ByteBus() = default;
    virtual void write_message(std::span<const std::uint8_t> bytes) = 0;
};

// /dev/i2c-N with the panel's 7-bit address selected. Throws std::runtime_error naming the
// device: missing, permission denied, not an I2C adapter, a write the bus refused.
class I2cDevBus final : public ByteBus {
  public:
    I2cDevBus(const std::string& device, int address);
    I2cDevBus(const I2cDevBus&) = delete;
    I2cDevBus& operator=(const I2cDevBus&) = delete;
    ~I2cDevBus() override;
    void write_message(std::span<const std::uint8_t> bytes) override;

  private:
    std::string device_;
    int fd_ = -1;
};

// A file or pipe standing in for the bus: each message's bytes are written as they are.
class FdByteBus final : public ByteBus {
  public:
    FdByteBus(int fd, std::string name) : fd_(fd), name_(std::move(name)) {}
    void write_message(std::span<const std::uint8_t> bytes) override;

  private:
    int fd_;
    std::string name_;
};

enum class OledController {
    ssd1306,  // 128 columns, one write of the whole frame (horizontal addressing)
    sh1106,   // 132 columns of RAM, the panel's 128 start at column 2; page addressing only
};

// Control bytes (Co = 0): a stream of commands, or a stream of display RAM data.
constexpr std::uint8_t kOledCommandStream = 0x00;
constexpr std::uint8_t kOledDataStream = 0x40;

class OledDisplay final : public hal::Display {
  public:
    // Sends the controller's initialisation for a 128x64 panel.
    OledDisplay(std::unique_ptr<ByteBus> bus, OledController controller);
    int width_px() const override { return 128; }
    int height_px() const override { return 64; }
    // Resends only the pages (8-pixel rows) that changed since the last frame.
    void show(const hal::MonoBitmap& frame) override;

    static std::vector<std::uint8_t> init_commands(OledController controller);

  private:
    using Pages = std::array<std::array<std::uint8_t, 128>, 8>;
    void send_commands(std::vector<std::uint8_t> commands);
    void send_data(std::span<const std::uint8_t> data);

    std::unique_ptr<ByteBus> bus_;
    OledController controller_;
    std::optional<Pages> shown_;
};

}  // namespace calbox::drivers
