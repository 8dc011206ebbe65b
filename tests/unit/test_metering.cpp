// The box's metered capture, step by step, on frames made by hand: what it asks the camera for,
// what it hands on to be measured, and what its record keeps.
#include <CppUTest/TestHarness.h>

#include <chrono>
#include <nlohmann/json.hpp>

#include "firmware/cycle/metering.hpp"

using namespace calbox;
using std::chrono::microseconds;

namespace {

// A 200 x 100 frame: its left half at `left_dn`, its right half at `right_dn`, a dark mark
// (10 DN, 6 x 6 px) every 20 px, taken at `exposure_us` (0: the camera does not say).
hal::Frame two_halves(int left_dn, int right_dn, long exposure_us) {
    hal::Frame f;
    f.width_px = 200;
    f.height_px = 100;
    f.stride_bytes = 200;
    f.pixels.resize(200 * 100);
    for (int y = 0; y < 100; ++y)
        for (int x = 0; x < 200; ++x)
            f.pixels[static_cast<std::size_t>(y * 200 + x)] = static_cast<std::uint8_t>(
                x % 20 < 6 && y % 20 < 6 ? 10 : (x < 100 ? left_dn : right_dn));
    f.metadata.exposure = microseconds(exposure_us);
    f.metadata.analogue_gain = 2;
    return f;
}

}  // namespace

TEST_GROUP(MeteredCapture){};

TEST(MeteredCapture, a_clipped_frame_is_read_again_at_half_then_captured_at_the_target) {
    firmware::MeteredCapture metering("target", 2, {});
    CHECK_FALSE(metering.first().exposure.has_value());  // the camera's own, the first time
    const auto again = metering.read(two_halves(100, 255, 10000));
    CHECK(again.has_value());
    CHECK_EQUAL(1, again->frame_count);
    CHECK_EQUAL(5000, again->exposure->count());
    DOUBLES_EQUAL(2, *again->analogue_gain, 0);  // the gain held where the camera had it
    // At half: the right half at 150, the left at 50: x1.5 puts the bright side at 225.
    CHECK_FALSE(metering.read(two_halves(50, 150, 5000)).has_value());
    const auto captures = metering.captures();
    CHECK_EQUAL(1u, captures.size());
    CHECK_EQUAL(2, captures[0].frame_count);
    CHECK_EQUAL(7500, captures[0].exposure->count());
    const auto frames = metering.finish({{two_halves(75, 225, 7500), two_halves(75, 225, 7500)}});
    CHECK_EQUAL(2u, frames.size());
    const auto& record = metering.record();
    CHECK_EQUAL(2u, record.readings.size());
    CHECK(record.clipped_before > 0.4);  // the right half less its marks
    DOUBLES_EQUAL(0, record.clipped_after, 0);
    CHECK_EQUAL(7500, record.exposure.count());
    STRCMP_CONTAINS("target: exposure 7500 us; the work area ", metering.summary().c_str());
    STRCMP_CONTAINS(" % clipped before, 0.0 % after; ", metering.summary().c_str());
    // The next capture starts where this one ended.
    CHECK_EQUAL(7500, metering.next_start().exposure->count());
    const nlohmann::json j = record;
    CHECK_EQUAL(5000, j.at("readings").at(1).at("exposure_us").get<long>());
    CHECK_FALSE(j.at("bracketed").get<bool>());
}

TEST(MeteredCapture, a_frame_already_right_is_the_capture_itself) {
    firmware::MeteredCapture metering("verify", 1, {}, {1, microseconds(7500), 2.0});
    CHECK_EQUAL(7500, metering.first().exposure->count());
    CHECK_FALSE(metering.read(two_halves(75, 210, 7500)).has_value());
    CHECK(metering.captures().empty());
    const auto frames = metering.finish({});
    CHECK_EQUAL(1u, frames.size());
    CHECK_EQUAL(210, frames[0].pixels[50 * 200 + 150]);
    STRCMP_CONTAINS("held as it is", metering.record().why.c_str());
}

TEST(MeteredCapture, a_dark_side_is_bracketed_and_merged_on_the_short_ones_scale) {
    firmware::MeteredCapture metering("target", 1, {});
    CHECK_FALSE(metering.read(two_halves(12, 220, 10000)).has_value());
    const auto captures = metering.captures();
    CHECK_EQUAL(2u, captures.size());
    CHECK_EQUAL(20833, captures[0].exposure->count());  // 25 / 12 of the reading's
    CHECK_EQUAL(10000, captures[1].exposure->count());
    // The long frame at twice the light (the right half clipped), the short as read.
    const auto frames =
        metering.finish({{two_halves(24, 255, 20000)}, {two_halves(12, 220, 10000)}});
    CHECK_EQUAL(12, frames[0].pixels[50 * 200 + 50]);    // the long one, halved
    CHECK_EQUAL(220, frames[0].pixels[50 * 200 + 150]);  // the short one
    CHECK_EQUAL(10000, frames[0].metadata.exposure.count());
    CHECK_EQUAL(10000, metering.record().short_exposure.count());
    CHECK(metering.record().from_short_share > 0.4);
    STRCMP_CONTAINS("and 10000 us, merged (", metering.summary().c_str());
    CHECK_EQUAL(20000, metering.next_start().exposure->count());  // the long one
}

TEST(MeteredCapture, a_camera_that_does_not_say_its_exposure_is_taken_at_its_own) {
    firmware::MeteredCapture metering("target", 1, {});
    CHECK_FALSE(metering.read(two_halves(100, 255, 0)).has_value());
    CHECK(metering.captures().empty());
    CHECK_EQUAL(1u, metering.finish({}).size());
    STRCMP_CONTAINS("target: exposure the camera's own; ", metering.summary().c_str());
    STRCMP_CONTAINS("the camera does not report its exposure", metering.summary().c_str());
    CHECK_FALSE(metering.next_start().exposure.has_value());
    // Asked for a burst, it takes the burst at the camera's own.
    firmware::MeteredCapture burst("target", 3, {});
    (void)burst.read(two_halves(100, 255, 0));
    CHECK_EQUAL(1u, burst.captures().size());
    CHECK_EQUAL(3, burst.captures()[0].frame_count);
    CHECK_FALSE(burst.captures()[0].exposure.has_value());
}

TEST(MeteredCapture, marks_in_a_line_leave_the_frame_less_its_border_to_meter) {
    firmware::MeteredCapture metering("target", 1, {{10, 50}, {100, 50}, {190, 50}});
    CHECK_FALSE(metering.read(two_halves(100, 180, 10000)).has_value());
    DOUBLES_EQUAL(180, metering.record().readings[0].light.bright_dn, 0);
}
