#include <CppUTest/TestHarness.h>
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdint>
#include <string>
#include <vector>

#include "drivers/framebuffer_display.hpp"
#include "drivers/oled_display.hpp"
#include "tests/support/device_errors.hpp"

using namespace calbox;
using Bytes = std::vector<std::uint8_t>;

namespace {

// Keeps each I2C transaction apart, as the bus sees them.
struct RecordingBus final : drivers::ByteBus {
    std::vector<Bytes>* messages;
    explicit RecordingBus(std::vector<Bytes>* into) : messages(into) {}
    void write_message(std::span<const std::uint8_t> bytes) override {
        messages->emplace_back(bytes.begin(), bytes.end());
    }
};

Bytes read_pipe(int fd) {
    Bytes all;
    std::uint8_t chunk[4096];
    for (;;) {
        const ssize_t n = ::read(fd, chunk, sizeof chunk);
        if (n <= 0) break;
        all.insert(all.end(), chunk, chunk + n);
    }
    return all;
}

hal::MonoBitmap known_frame();

// What a display starting up and showing the known frame sends down a pipe for a bus.
Bytes stream_through_a_pipe(drivers::OledController controller) {
    int fds[2];
    if (::pipe(fds) != 0) FAIL("pipe failed");
    {
        drivers::OledDisplay display(std::make_unique<drivers::FdByteBus>(fds[1], "pipe"),
                                     controller);
        display.show(known_frame());
    }
    ::close(fds[1]);
    Bytes stream = read_pipe(fds[0]);
    ::close(fds[0]);
    return stream;
}

hal::MonoBitmap known_frame() {
    hal::MonoBitmap frame(128, 64);
    frame.set(0, 0, true);     // page 0, column 0, bit 0
    frame.set(5, 10, true);    // page 1, column 5, bit 2
    frame.set(127, 63, true);  // page 7, column 127, bit 7
    frame.set(64, 31, true);   // page 3, column 64, bit 7
    frame.set(64, 24, true);   // page 3, column 64, bit 0
    return frame;
}

// The frame's display RAM worked out by hand from the datasheets' page layout.
Bytes known_frame_ram() {
    Bytes ram(1024, 0);
    ram[0 * 128 + 0] = 0x01;
    ram[1 * 128 + 5] = 0x04;
    ram[7 * 128 + 127] = 0x80;
    ram[3 * 128 + 64] = 0x81;
    return ram;
}

const Bytes kSsd1306Init = {0x00, 0xAE, 0xD5, 0x80, 0xA8, 0x3F, 0xD3, 0x00, 0x40,
                            0x8D, 0x14, 0x20, 0x00, 0xA1, 0xC8, 0xDA, 0x12, 0x81,
                            0xCF, 0xD9, 0xF1, 0xDB, 0x40, 0xA4, 0xA6, 0xAF};
const Bytes kSh1106Init = {0x00, 0xAE, 0xD5, 0x80, 0xA8, 0x3F, 0xD3, 0x00, 0x40, 0xAD, 0x8B, 0xA1,
                           0xC8, 0xDA, 0x12, 0x81, 0x80, 0xD9, 0x22, 0xDB, 0x35, 0xA4, 0xA6, 0xAF};

Bytes concat(std::initializer_list<Bytes> parts) {
    Bytes all;
    for (const auto& p : parts) all.insert(all.end(), p.begin(), p.end());
    return all;
}

// Sized first: GCC 12 at -O3 warns (a false -Warray-bounds) on inserting into a one-byte vector.
Bytes with_data_byte(const Bytes& ram, std::size_t from, std::size_t count) {
    Bytes message(count + 1, 0x40);
    std::copy_n(ram.begin() + static_cast<std::ptrdiff_t>(from), count, message.begin() + 1);
    return message;
}

}  // namespace

TEST_GROUP(OledDisplay){};

TEST(OledDisplay, ssd1306_byte_stream_through_a_pipe_matches_the_protocol) {
    const Bytes stream = stream_through_a_pipe(drivers::OledController::ssd1306);
    const Bytes expected = concat({kSsd1306Init,
                                   {0x00, 0x21, 0x00, 0x7F, 0x22, 0x00, 0x07},
                                   with_data_byte(known_frame_ram(), 0, 1024)});
    CHECK_EQUAL(expected.size(), stream.size());
    CHECK(expected == stream);
}

TEST(OledDisplay, ssd1306_sends_a_whole_frame_in_one_write_then_only_changed_pages) {
    std::vector<Bytes> messages;
    drivers::OledDisplay display(std::make_unique<RecordingBus>(&messages),
                                 drivers::OledController::ssd1306);
    display.show(known_frame());
    CHECK_EQUAL(3U, messages.size());  // init, address window, one data write of 1024
    CHECK_EQUAL(1025U, messages[2].size());

    messages.clear();
    display.show(known_frame());
    CHECK_EQUAL(0U, messages.size());  // nothing changed, nothing sent

    hal::MonoBitmap next = known_frame();
    next.set(10, 20, true);  // page 2
    next.set(11, 28, true);  // page 3
    next.set(0, 60, true);   // page 7
    display.show(next);
    Bytes ram = known_frame_ram();
    ram[2 * 128 + 10] |= 0x10;
    ram[3 * 128 + 11] |= 0x10;
    ram[7 * 128 + 0] |= 0x10;
    CHECK_EQUAL(4U, messages.size());
    CHECK(messages[0] == (Bytes{0x00, 0x21, 0x00, 0x7F, 0x22, 0x02, 0x03}));
    CHECK(messages[1] == with_data_byte(ram, 2 * 128, 256));
    CHECK(messages[2] == (Bytes{0x00, 0x21, 0x00, 0x7F, 0x22, 0x07, 0x07}));
    CHECK(messages[3] == with_data_byte(ram, 7 * 128, 128));
}

TEST(OledDisplay, sh1106_writes_page_by_page_from_column_two) {
    const Bytes stream = stream_through_a_pipe(drivers::OledController::sh1106);
    Bytes expected = kSh1106Init;
    const Bytes ram = known_frame_ram();
    for (std::uint8_t page = 0; page < 8; ++page) {
        const Bytes address{0x00, static_cast<std::uint8_t>(0xB0 + page), 0x02, 0x10};
        expected = concat({expected, address, with_data_byte(ram, page * 128U, 128)});
    }
    CHECK_EQUAL(expected.size(), stream.size());
    CHECK(expected == stream);
}

TEST(OledDisplay, sh1106_resends_only_the_changed_page) {
    std::vector<Bytes> messages;
    drivers::OledDisplay display(std::make_unique<RecordingBus>(&messages),
                                 drivers::OledController::sh1106);
    display.show(known_frame());
    CHECK_EQUAL(1U + 16U, messages.size());
    messages.clear();
    hal::MonoBitmap next = known_frame();
    next.set(0, 0, false);
    display.show(next);
    Bytes ram = known_frame_ram();
    ram[0] = 0x00;
    CHECK_EQUAL(2U, messages.size());
    CHECK(messages[0] == (Bytes{0x00, 0xB0, 0x02, 0x10}));
    CHECK(messages[1] == with_data_byte(ram, 0, 128));
}

TEST(OledDisplay, refuses_a_frame_of_another_size) {
    std::vector<Bytes> messages;
    drivers::OledDisplay display(std::make_unique<RecordingBus>(&messages),
                                 drivers::OledController::ssd1306);
    CHECK_THROWS(std::invalid_argument, display.show(hal::MonoBitmap(128, 32)));
}

TEST(OledDisplay, i2c_device_errors_name_the_device) {
    STRCMP_CONTAINS(
        "/dev/i2c-97: cannot open: No such file or directory",
        test::construction_error([] { drivers::I2cDevBus("/dev/i2c-97", 0x3C); }).c_str());
    test::ScratchFile plain("not an adapter");
    STRCMP_CONTAINS(
        (plain.path + ": not an I2C adapter").c_str(),
        test::construction_error([&] { drivers::I2cDevBus(plain.path, 0x3C); }).c_str());
    STRCMP_CONTAINS("outside 0x03-0x77", test::construction_error([&] {
                                             drivers::I2cDevBus(plain.path, 0x90);
                                         }).c_str());
    STRCMP_CONTAINS(
        (plain.path + ": cannot open: Permission denied").c_str(),
        test::error_as_unprivileged_user([&] { drivers::I2cDevBus(plain.path, 0x3C); }).c_str());
}

TEST(OledDisplay, a_bus_gone_mid_use_is_one_clear_error) {
    int fds[2];
    CHECK_EQUAL(0, ::pipe(fds));
    ::close(fds[0]);  // the far end is gone: EPIPE, once SIGPIPE no longer ends the process
    const auto previous = std::signal(SIGPIPE, SIG_IGN);
    drivers::OledDisplay* display = nullptr;
    const std::string error = test::construction_error([&] {
        display = new drivers::OledDisplay(std::make_unique<drivers::FdByteBus>(fds[1], "bus"),
                                           drivers::OledController::ssd1306);
    });
    std::signal(SIGPIPE, previous);
    ::close(fds[1]);
    delete display;
    STRCMP_CONTAINS("bus: write failed: Broken pipe", error.c_str());
}

TEST_GROUP(Framebuffer){};

TEST(Framebuffer, packs_32_bit_pixels_scaled_and_centred) {
    drivers::FramebufferFormat f;
    f.width_px = 300;  // scale 2 (256 wide), 22 px margin left; 150 tall: 11 px margin top
    f.height_px = 150;
    f.bits_per_pixel = 32;
    f.line_length_bytes = 1216;  // padded rows
    f.red = {16, 8};
    f.green = {8, 8};
    f.blue = {0, 8};
    hal::MonoBitmap frame(128, 64);
    frame.set(0, 0, true);
    frame.set(127, 63, true);
    const auto screen = drivers::pack_framebuffer(frame, f);
    CHECK_EQUAL(1216U * 150U, screen.size());
    auto pixel = [&](int x, int y) {
        const std::size_t at = static_cast<std::size_t>(y) * 1216 + static_cast<std::size_t>(x) * 4;
        return std::uint32_t{screen[at]} | std::uint32_t{screen[at + 1]} << 8 |
               std::uint32_t{screen[at + 2]} << 16 | std::uint32_t{screen[at + 3]} << 24;
    };
    CHECK_EQUAL(0x00FFFFFFU, pixel(22, 11));
    CHECK_EQUAL(0x00FFFFFFU, pixel(23, 12));
    CHECK_EQUAL(0U, pixel(24, 11));
    CHECK_EQUAL(0U, pixel(21, 11));
    CHECK_EQUAL(0x00FFFFFFU, pixel(22 + 255, 11 + 127));
    CHECK_EQUAL(0U, pixel(22 + 256, 11 + 127));
}

TEST(Framebuffer, packs_rgb565_and_mono) {
    drivers::FramebufferFormat f;
    f.width_px = 128;
    f.height_px = 64;
    f.bits_per_pixel = 16;
    f.line_length_bytes = 256;
    f.red = {11, 5};
    f.green = {5, 6};
    f.blue = {0, 5};
    hal::MonoBitmap frame(128, 64);
    frame.set(3, 2, true);
    auto screen = drivers::pack_framebuffer(frame, f);
    CHECK_EQUAL(0xFF, screen[2 * 256 + 6]);
    CHECK_EQUAL(0xFF, screen[2 * 256 + 7]);
    CHECK_EQUAL(0x00, screen[2 * 256 + 8]);

    f.bits_per_pixel = 1;
    f.line_length_bytes = 16;
    f.red = f.green = f.blue = {0, 1};
    screen = drivers::pack_framebuffer(frame, f);
    CHECK_EQUAL(0x10, screen[2 * 16 + 0]);  // x = 3: the fourth bit from the top
    f.mono_one_is_black = true;
    screen = drivers::pack_framebuffer(frame, f);
    CHECK_EQUAL(0xEF, screen[2 * 16 + 0]);
    CHECK_EQUAL(0xFF, screen[0]);
}

TEST(Framebuffer, refuses_what_it_cannot_show) {
    drivers::FramebufferFormat f;
    f.width_px = 100;
    f.height_px = 64;
    f.bits_per_pixel = 32;
    f.line_length_bytes = 400;
    const hal::MonoBitmap frame(128, 64);
    CHECK_THROWS(std::invalid_argument, drivers::pack_framebuffer(frame, f));
    f.width_px = 128;
    f.line_length_bytes = 512;
    f.bits_per_pixel = 12;
    CHECK_THROWS(std::invalid_argument, drivers::pack_framebuffer(frame, f));
}

TEST(Framebuffer, device_errors_name_the_device) {
    STRCMP_CONTAINS(
        "/dev/fb97: cannot open: No such file or directory",
        test::construction_error([] { drivers::FramebufferDisplay("/dev/fb97"); }).c_str());
    test::ScratchFile plain("not a framebuffer");
    STRCMP_CONTAINS(
        (plain.path + ": not a framebuffer").c_str(),
        test::construction_error([&] { drivers::FramebufferDisplay{plain.path}; }).c_str());
    STRCMP_CONTAINS(
        (plain.path + ": cannot open: Permission denied").c_str(),
        test::error_as_unprivileged_user([&] { drivers::FramebufferDisplay{plain.path}; }).c_str());
}
