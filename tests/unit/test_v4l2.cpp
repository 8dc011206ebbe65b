// The camera drivers. V4L2 against a node that speaks the kernel's streaming protocol from memory
// (tests/mocks/fake_v4l2_device.hpp): formats, frames, controls, and the error paths a real
// camera takes (no device, unplugged mid-burst, frames that never come).
#include <CppUTest/TestHarness.h>
#include <poll.h>

#include <cmath>
#include <memory>
#include <string>

#include "drivers/libcamera_camera.hpp"
#include "drivers/v4l2_camera.hpp"
#include "tests/mocks/fake_v4l2_device.hpp"
#include "tests/support/device_errors.hpp"

using namespace calbox;

namespace {

hal::CaptureResult wait_for(drivers::V4l2Camera& camera) {
    pollfd p{camera.completion_fd(), POLLIN, 0};
    CHECK_EQUAL_TEXT(1, ::poll(&p, 1, 10000), "the capture signals its end");
    return camera.take_frames();
}

drivers::V4l2Settings small(int settle = 2) {
    drivers::V4l2Settings s;
    s.width_px = 640;
    s.height_px = 480;
    s.frames_to_settle = settle;
    s.frame_timeout = std::chrono::milliseconds(200);
    return s;
}

}  // namespace

TEST_GROUP(V4l2Camera){};

TEST(V4l2Camera, a_yuyv_burst_arrives_as_its_y_plane_after_the_settling_frames) {
    auto device = std::make_unique<test::FakeV4l2Device>();
    auto* fake = device.get();
    drivers::V4l2Camera camera(std::move(device), small());
    CHECK_EQUAL(V4L2_PIX_FMT_YUYV, camera.pixel_format());
    hal::CaptureRequest request;
    request.frame_count = 3;
    request.exposure = std::chrono::milliseconds(10);
    request.analogue_gain = 2.0;
    camera.start_capture(request);
    const auto result = wait_for(camera);
    CHECK_TEXT(result.ok(), result.error.c_str());
    CHECK_EQUAL(3u, result.frames.size());
    for (std::size_t f = 0; f < result.frames.size(); ++f) {
        const auto& frame = result.frames[f];
        CHECK_EQUAL(640, frame.width_px);
        CHECK_EQUAL(480, frame.height_px);
        const auto sequence = static_cast<std::uint32_t>(f + 2);  // two dropped while settling
        CHECK_EQUAL(sequence, frame.metadata.sequence);
        int wrong = 0;
        for (int y = 0; y < 480; ++y)
            for (int x = 0; x < 640; ++x)
                wrong += frame.pixels[static_cast<std::size_t>(y) * 640 + x] !=
                         test::FakeV4l2Device::level(x, y, sequence);
        CHECK_EQUAL(0, wrong);
        CHECK_EQUAL(10000, frame.metadata.exposure.count());
    }
    // Manual exposure in V4L2's 100 us units; the gain twice the control's default (unity).
    CHECK_EQUAL(V4L2_EXPOSURE_MANUAL, fake->controls[V4L2_CID_EXPOSURE_AUTO]);
    CHECK_EQUAL(100, fake->controls[V4L2_CID_EXPOSURE_ABSOLUTE]);
    CHECK_EQUAL(64, fake->controls[V4L2_CID_GAIN]);
    CHECK_EQUAL(1, fake->streamoff_calls);
    // A second capture on the same buffers.
    request.frame_count = 1;
    camera.start_capture(request);
    CHECK_TEXT(wait_for(camera).ok(), "a second capture");
}

TEST(V4l2Camera, grey_is_preferred_and_the_size_is_what_the_driver_gives) {
    auto device = std::make_unique<test::FakeV4l2Device>();
    device->formats = {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY};
    drivers::V4l2Settings settings = small(0);
    settings.width_px = 4056;
    settings.height_px = 3040;
    drivers::V4l2Camera camera(std::move(device), settings);
    CHECK_EQUAL(V4L2_PIX_FMT_GREY, camera.pixel_format());
    CHECK_EQUAL(1280, camera.width_px());
    CHECK_EQUAL(720, camera.height_px());
    camera.start_capture({});
    const auto result = wait_for(camera);
    CHECK_TEXT(result.ok(), result.error.c_str());
    CHECK_EQUAL(1280, result.frames.at(0).width_px);
    CHECK_EQUAL(test::FakeV4l2Device::level(1000, 700, 0),
                result.frames[0].pixels[700 * 1280 + 1000]);
    // At the camera's own exposure the frame says what it chose (read back: 156 x 100 us), so
    // that the box's metering can scale from it.
    CHECK_EQUAL(15600, result.frames[0].metadata.exposure.count());
}

TEST(V4l2Camera, mjpeg_frames_are_decoded_to_grey) {
    auto device = std::make_unique<test::FakeV4l2Device>();
    device->formats = {V4L2_PIX_FMT_MJPEG};
    drivers::V4l2Camera camera(std::move(device), small(1));
    CHECK_EQUAL(V4L2_PIX_FMT_MJPEG, camera.pixel_format());
    camera.start_capture({});
    const auto result = wait_for(camera);
    CHECK_TEXT(result.ok(), result.error.c_str());
    const auto& frame = result.frames.at(0);
    double sum = 0;
    for (int y = 0; y < 480; ++y)
        for (int x = 0; x < 640; ++x)
            sum += std::abs(frame.pixels[static_cast<std::size_t>(y) * 640 + x] -
                            test::FakeV4l2Device::level(x, y, 1));
    CHECK_TEXT(sum / (640 * 480) < 3, std::to_string(sum / (640 * 480)).c_str());
}

TEST(V4l2Camera, unplugged_mid_burst_the_capture_fails_naming_the_device_and_frame) {
    auto device = std::make_unique<test::FakeV4l2Device>();
    device->gone_at_frame = 4;
    auto* fake = device.get();
    drivers::V4l2Camera camera(std::move(device), small());
    hal::CaptureRequest request;
    request.frame_count = 5;
    camera.start_capture(request);
    const auto result = wait_for(camera);
    CHECK_FALSE(result.ok());
    CHECK(result.frames.empty());
    STRCMP_CONTAINS("/dev/video-fake: take frame 4 of the capture: No such device",
                    result.error.c_str());
    CHECK_EQUAL(1, fake->streamoff_calls);
}

TEST(V4l2Camera, frames_that_never_come_end_the_capture_after_the_timeout) {
    auto device = std::make_unique<test::FakeV4l2Device>();
    device->frames_stall = true;
    drivers::V4l2Camera camera(std::move(device), small());
    camera.start_capture({});
    const auto result = wait_for(camera);
    STRCMP_EQUAL("/dev/video-fake: no frame within 200 ms", result.error.c_str());
}

TEST(V4l2Camera, a_camera_without_manual_exposure_says_so_rather_than_exposing_itself) {
    auto device = std::make_unique<test::FakeV4l2Device>();
    device->controls.erase(V4L2_CID_EXPOSURE_ABSOLUTE);
    drivers::V4l2Camera camera(std::move(device), small());
    hal::CaptureRequest request;
    request.exposure = std::chrono::milliseconds(20);
    camera.start_capture(request);
    STRCMP_CONTAINS("/dev/video-fake: set the exposure time: Invalid argument",
                    wait_for(camera).error.c_str());
}

TEST(V4l2Camera, a_device_without_a_usable_format_or_node_is_refused_by_name) {
    auto device = std::make_unique<test::FakeV4l2Device>();
    device->formats = {V4L2_PIX_FMT_H264};
    try {
        drivers::V4l2Camera camera(std::move(device), small());
        FAIL("an H.264-only camera was accepted");
    } catch (const std::runtime_error& e) {
        STRCMP_EQUAL("/dev/video-fake: offers none of GREY, YUYV or MJPEG at 640x480", e.what());
    }
    try {
        drivers::open_v4l2_device("/dev/calbox-no-such-video");
        FAIL("a missing node was opened");
    } catch (const std::runtime_error& e) {
        STRCMP_EQUAL("/dev/calbox-no-such-video (V4L2 camera): open: No such file or directory",
                     e.what());
    }
    // A node that is not a V4L2 device at all.
    CHECK_THROWS(std::runtime_error, drivers::open_v4l2_device("/dev/null"));
    // A node the service's user may not open: the group it needs is named.
    const test::ScratchFile root_only("");
    STRCMP_CONTAINS(
        (root_only.path + " (V4L2 camera): open: Permission denied (is the user in the device's "
                          "group?")
            .c_str(),
        test::error_as_unprivileged_user([&] {
            drivers::open_v4l2_device(root_only.path);
        }).c_str());
}

// libcamera on a machine without a camera (this one, and CI's): one line saying so, after
// libcamera's manager started and looked. Its capture paths need a camera: README, Devices.
TEST_GROUP(LibcameraCamera){};

TEST(LibcameraCamera, without_a_camera_it_says_libcamera_found_none) {
    try {
        drivers::open_libcamera_camera({});
        FAIL("a camera was found: this test expects a machine without one");
    } catch (const std::runtime_error& e) {
        STRCMP_EQUAL("libcamera found no camera", e.what());
    }
}
