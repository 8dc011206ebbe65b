// The cycle's settings tables: [cycle] (the button and the photos), [setup] (the camera's and the
// plane's boards, the reference marks) and [records] (what each cycle keeps). Ranges are what the
// box can do sensibly: a long press under 0.5 s is an accidental one; more than 16 frames do not
// lower the noise further than the target's own texture.
#include <array>

#include "core/geometry/pattern_spec.hpp"
#include "firmware/cycle/cycle.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;
using setting_text::decimal;
using setting_text::flag;
using setting_text::flag_text;
using setting_text::number;
using setting_text::one_line;
using setting_text::whole;

std::string pattern(std::string_view text) {
    try {
        (void)geometry::parse_pattern_spec(one_line(text));
    } catch (const std::invalid_argument& e) {
        throw ConfigError(e.what());
    }
    return std::string(text);
}

const SettingKey<CycleSettings> kCycleKeys[] = {
    {{"frames_per_capture",
      K::integer,
      "photos",
      1,
      16,
      {},
      false,
      "photos averaged per capture (more: less noise, longer capture)"},
     [](const CycleSettings& s) { return std::to_string(s.frames_per_capture); },
     [](CycleSettings& s, const KeyInfo& k, std::string_view t) {
         s.frames_per_capture = static_cast<int>(whole(k, t));
     }},
    {{"long_press_ms",
      K::integer,
      "ms",
      500,
      10000,
      {},
      false,
      "a press at least this long cancels (in review: cancels instead of applying)"},
     [](const CycleSettings& s) { return std::to_string(s.long_press.count()); },
     [](CycleSettings& s, const KeyInfo& k, std::string_view t) {
         s.long_press = std::chrono::milliseconds(whole(k, t));
     }},
};

const SettingKey<CycleSettings> kSetupKeys[] = {
    {{"calibration_views",
      K::integer,
      "views",
      3,
      60,
      {},
      false,
      "board views asked for in the camera's set-up"},
     [](const CycleSettings& s) { return std::to_string(s.calibration_views); },
     [](CycleSettings& s, const KeyInfo& k, std::string_view t) {
         s.calibration_views = static_cast<int>(whole(k, t));
     }},
    {{"calibration_pattern",
      K::text,
      {},
      0,
      0,
      {},
      false,
      "the board held in front of the camera (calbox camera --pattern's form)"},
     [](const CycleSettings& s) { return s.calibration_pattern; },
     [](CycleSettings& s, const KeyInfo&, std::string_view t) {
         s.calibration_pattern = pattern(t);
     }},
    {{"plane_pattern", K::text, {}, 0, 0, {}, false, "the board laid on the bed for the plane"},
     [](const CycleSettings& s) { return s.plane_pattern; },
     [](CycleSettings& s, const KeyInfo&, std::string_view t) { s.plane_pattern = pattern(t); }},
    {{"plane_board_thickness_mm",
      K::number,
      "mm",
      0,
      20,
      {},
      false,
      "the plane board's thickness: the bed is this far below its surface"},
     [](const CycleSettings& s) { return number(s.plane_board_thickness_mm); },
     [](CycleSettings& s, const KeyInfo& k, std::string_view t) {
         s.plane_board_thickness_mm = decimal(k, t);
     }},
    {{"reference_marks",
      K::text,
      {},
      0,
      0,
      {},
      false,
      "the fixed reference marks' dictionary (OpenCV's name): at least 2 stuck outside the work "
      "area, seen with the plane and checked at each cycle's start; \"none\": no camera check"},
     [](const CycleSettings& s) { return s.reference_marks; },
     [](CycleSettings& s, const KeyInfo&, std::string_view t) {
         const std::string marks = one_line(t);
         try {
             if (marks != kNoReferenceMarks) (void)geometry::aruco_dictionary_id(marks);
         } catch (const std::invalid_argument& e) {
             throw ConfigError(e.what());
         }
         s.reference_marks = marks;
     }},
    {{"camera_moved_limit_mm",
      K::number,
      "mm",
      0.005,
      5,
      {},
      false,
      "how far the reference marks may seem to move on the bed before a cycle stops (the camera "
      "has moved)"},
     [](const CycleSettings& s) { return number(s.camera_moved_limit_mm); },
     [](CycleSettings& s, const KeyInfo& k, std::string_view t) {
         s.camera_moved_limit_mm = decimal(k, t);
     }},
};

const SettingKey<CycleSettings> kRecordsKeys[] = {
    {{"keep_cycles",
      K::integer,
      "cycles",
      1,
      100000,
      {},
      false,
      "cycle records kept in the data directory; older ones are pruned"},
     [](const CycleSettings& s) { return std::to_string(s.records.keep_cycles); },
     [](CycleSettings& s, const KeyInfo& k, std::string_view t) {
         s.records.keep_cycles = static_cast<int>(whole(k, t));
     }},
    {{"max_size_mb",
      K::integer,
      "MB",
      1,
      1000000,
      {},
      false,
      "the records' total size; the oldest are pruned past it"},
     [](const CycleSettings& s) { return std::to_string(s.records.max_bytes / 1000000U); },
     [](CycleSettings& s, const KeyInfo& k, std::string_view t) {
         s.records.max_bytes = static_cast<std::uintmax_t>(whole(k, t)) * 1000000U;
     }},
    {{"keep_photos", K::flag, {}, 0, 0, {}, false, "keep each cycle's photos (PNG) in its record"},
     [](const CycleSettings& s) { return flag_text(s.records.keep_photos); },
     [](CycleSettings& s, const KeyInfo& k, std::string_view t) {
         s.records.keep_photos = flag(k, t);
     }},
};

const std::array<SettingsTable<CycleSettings>, 3> kTables = {{
    {"cycle", kCycleKeys},
    {"setup", kSetupKeys},
    {"records", kRecordsKeys},
}};

}  // namespace

std::span<const SettingsTable<CycleSettings>> cycle_settings_tables() {
    return kTables;
}

}  // namespace calbox::firmware
