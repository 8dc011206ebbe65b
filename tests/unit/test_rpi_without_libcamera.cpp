// A calbox built with CALBOX_LIBCAMERA=OFF (drivers/libcamera_absent.cpp linked in place of the
// libcamera driver): the rpi board goes to the V4L2 node and its failure says both why libcamera
// was not tried and what V4L2 found.
#include <CppUTest/TestHarness.h>

#include <stdexcept>
#include <string>

#include "board/rpi/rpi_board.hpp"
#include "drivers/libcamera_camera.hpp"
#include "drivers/timerfd_clock.hpp"

using namespace calbox;

TEST_GROUP(RpiWithoutLibcamera){};

TEST(RpiWithoutLibcamera, the_libcamera_stand_in_says_it_was_not_built) {
    try {
        drivers::open_libcamera_camera({});
        FAIL("a camera without libcamera");
    } catch (const std::runtime_error& e) {
        STRCMP_EQUAL("libcamera not built in (CALBOX_LIBCAMERA=OFF)", e.what());
    }
}

TEST(RpiWithoutLibcamera, the_board_falls_through_to_v4l2_and_names_both) {
    board::RpiSettings settings;
    settings.camera_v4l2_device = "/dev/calbox-no-such-video";
    drivers::TimerfdClock clock;
    try {
        board::open_rpi_devices(settings, clock);
        FAIL("devices opened on a machine without them");
    } catch (const std::runtime_error& e) {
        STRCMP_CONTAINS("the camera: libcamera not built in (CALBOX_LIBCAMERA=OFF), and "
                        "/dev/calbox-no-such-video",
                        e.what());
    }
}
