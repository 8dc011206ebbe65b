#include "drivers/oled_display.hpp"

#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <stdexcept>

#include "drivers/device_error.hpp"

namespace calbox::drivers {
namespace {

void write_all(int fd, std::span<const std::uint8_t> bytes, const std::string& name) {
    std::size_t done = 0;
    while (done < bytes.size()) {
        const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
        if (n < 0) {
            if (errno == EINTR) continue;
            throw device_error(name, "write failed");
        }
        done += static_cast<std::size_t>(n);
    }
}

}  // namespace

I2cDevBus::I2cDevBus(const std::string& device, int address) : device_(device) {
    if (address < 0x03 || address > 0x77) {
        throw std::runtime_error(device + ": I2C address " + std::to_string(address) +
                                 " is outside 0x03-0x77");
    }
    fd_ = ::open(device.c_str(), O_RDWR | O_CLOEXEC);
    if (fd_ < 0) throw device_error(device, "cannot open");
    if (::ioctl(fd_, I2C_SLAVE, static_cast<unsigned long>(address)) < 0) {
        const int why = errno;
        ::close(fd_);
        throw device_error(device, "not an I2C adapter, or the address is taken", why);
    }
}

I2cDevBus::~I2cDevBus() {
    if (fd_ >= 0) ::close(fd_);
}

// i2c-dev makes one transaction of each write(); a short write is a failed transaction.
void I2cDevBus::write_message(std::span<const std::uint8_t> bytes) {
    const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
    if (n < 0) throw device_error(device_, "write to the panel failed");
    if (static_cast<std::size_t>(n) != bytes.size()) {
        throw std::runtime_error(device_ + ": the panel took " + std::to_string(n) + " of " +
                                 std::to_string(bytes.size()) + " bytes");
    }
}

void FdByteBus::write_message(std::span<const std::uint8_t> bytes) {
    write_all(fd_, bytes, name_);
}

// The 128x64 initialisation from the controllers' datasheets (SSD1306 rev 1.1 application
// example; SH1106 V2.3 with its own DC-DC command), rows flipped so that page 0 is the top.
std::vector<std::uint8_t> OledDisplay::init_commands(OledController controller) {
    if (controller == OledController::ssd1306) {
        return {0xAE,        // display off
                0xD5, 0x80,  // clock divide and oscillator
                0xA8, 0x3F,  // multiplex ratio: 64 rows
                0xD3, 0x00,  // display offset 0
                0x40,        // start line 0
                0x8D, 0x14,  // charge pump on
                0x20, 0x00,  // horizontal addressing
                0xA1,        // column 127 is SEG0
                0xC8,        // COM scan from COM63
                0xDA, 0x12,  // alternative COM pins
                0x81, 0xCF,  // contrast
                0xD9, 0xF1,  // pre-charge
                0xDB, 0x40,  // VCOMH deselect level
                0xA4,        // display follows RAM
                0xA6,        // not inverted
                0xAF};       // display on
    }
    return {0xAE, 0xD5, 0x80, 0xA8, 0x3F, 0xD3, 0x00, 0x40,
            0xAD, 0x8B,  // DC-DC on (the SH1106 has no charge-pump command)
            0xA1, 0xC8, 0xDA, 0x12, 0x81, 0x80, 0xD9, 0x22,  // pre-charge
            0xDB, 0x35,                                      // VCOM deselect level
            0xA4, 0xA6, 0xAF};
}

OledDisplay::OledDisplay(std::unique_ptr<ByteBus> bus, OledController controller)
    : bus_(std::move(bus)), controller_(controller) {
    if (!bus_) throw std::invalid_argument("OledDisplay: no bus");
    send_commands(init_commands(controller));
}

void OledDisplay::send_commands(std::vector<std::uint8_t> commands) {
    commands.insert(commands.begin(), kOledCommandStream);
    bus_->write_message(commands);
}

void OledDisplay::send_data(std::span<const std::uint8_t> data) {
    std::vector<std::uint8_t> message;
    message.reserve(data.size() + 1);
    message.push_back(kOledDataStream);
    message.insert(message.end(), data.begin(), data.end());
    bus_->write_message(message);
}

// Display RAM: page p, column c holds rows 8p..8p+7 of column c, the top row in bit 0.
void OledDisplay::show(const hal::MonoBitmap& frame) {
    if (frame.width_px() != 128 || frame.height_px() != 64) {
        throw std::invalid_argument("OledDisplay: frames are 128x64, got " +
                                    std::to_string(frame.width_px()) + "x" +
                                    std::to_string(frame.height_px()));
    }
    Pages pages{};
    for (int page = 0; page < 8; ++page) {
        for (int x = 0; x < 128; ++x) {
            std::uint8_t byte = 0;
            for (int bit = 0; bit < 8; ++bit) {
                if (frame.at(x, page * 8 + bit)) byte |= static_cast<std::uint8_t>(1U << bit);
            }
            pages[static_cast<std::size_t>(page)][static_cast<std::size_t>(x)] = byte;
        }
    }
    auto changed = [&](int page) {
        const auto p = static_cast<std::size_t>(page);
        return !shown_ || (*shown_)[p] != pages[p];
    };
    if (controller_ == OledController::ssd1306) {
        // Runs of changed pages, each one address window and one data write; a whole new
        // frame is a single write of 1024 bytes.
        for (int first = 0; first < 8;) {
            if (!changed(first)) {
                ++first;
                continue;
            }
            int last = first;
            while (last + 1 < 8 && changed(last + 1)) ++last;
            send_commands({0x21, 0x00, 0x7F, 0x22, static_cast<std::uint8_t>(first),
                           static_cast<std::uint8_t>(last)});
            std::vector<std::uint8_t> data;
            for (int page = first; page <= last; ++page) {
                const auto& row = pages[static_cast<std::size_t>(page)];
                data.insert(data.end(), row.begin(), row.end());
            }
            send_data(data);
            first = last + 1;
        }
    } else {
        for (int page = 0; page < 8; ++page) {
            if (!changed(page)) continue;
            // Page address, then column 2 (low nibble, high nibble): the panel's first column.
            send_commands({static_cast<std::uint8_t>(0xB0 | page), 0x02, 0x10});
            send_data(pages[static_cast<std::size_t>(page)]);
        }
    }
    shown_ = pages;
}

}  // namespace calbox::drivers
