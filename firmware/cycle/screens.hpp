#pragma once
// What the 128x64 display shows, drawn in a 6x12 bitmap font (Terminus, see font_6x12.inc):
// five lines of 21 characters, the first inverted as a title. One drawing per screen the box
// has; each takes what it shows as plain values, so docs/appliance.md's pictures and the box's
// frames come from the same code.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "hal/display.hpp"

namespace calbox::firmware {

constexpr int kFontWidthPx = 6, kFontHeightPx = 12;
constexpr int kScreenColumns = 21;  // characters on a line of a 128 px display

// Draws `text` from (x, y), the glyphs' top left; characters outside ASCII 32..126 are drawn as
// '?'; what falls off the bitmap is clipped. `inverted`: dark text on a lit cell.
void draw_text(hal::MonoBitmap& bitmap, int x, int y, std::string_view text, bool inverted = false);

struct IdleScreen {
    std::string machine;      // "delta Marlin"
    std::string last_result;  // "last: 0.257 -> 0.003" or "no cycle yet"
    std::string verdict;      // the mode's goal: "goal met" or "short of goal"
};
struct ProgressScreen {
    std::string stage;                // "measure"
    double fraction = 0;              // of the cycle, 0..1
    std::optional<int> seconds_left;  // from the last cycle's stage times; none the first time
    std::string detail;               // one line
};
struct PromptScreen {
    std::string title;               // "set-up: camera"
    std::string instruction;         // wrapped over two lines
    std::string step;                // "view 3/12", may be empty
    std::optional<double> coverage;  // of the image by the views so far, 0..1
};
struct ReviewScreen {
    std::vector<std::string> change;  // up to two lines: what the correction changes
    std::string now, predicted;       // "now 0.257 mm", "after 0.003 mm"
};
struct DoneScreen {
    std::string before, after;  // "0.257 mm RMS"
};
// The page's TLS, as an owner checks a browser's warning against it: the https port and the
// certificate's SHA-256 fingerprint (fingerprint_lines, firmware/net/web_tls.hpp).
struct NetworkScreen {
    int https_port = 0;
    std::vector<std::string> fingerprint;  // four lines of four groups of four hex digits
};
struct ErrorScreen {
    int code = 0;         // the stage's state code, as the PLC's error register has it
    std::string hint;     // one line: what to check
    std::string message;  // the start of the error's text
};

hal::MonoBitmap draw_screen(const IdleScreen& s);
hal::MonoBitmap draw_screen(const ProgressScreen& s);
hal::MonoBitmap draw_screen(const PromptScreen& s);
hal::MonoBitmap draw_screen(const ReviewScreen& s);
hal::MonoBitmap draw_screen(const DoneScreen& s);
hal::MonoBitmap draw_screen(const ErrorScreen& s);
hal::MonoBitmap draw_screen(const NetworkScreen& s);

// Words over lines of at most `width` characters (a longer word is cut), at most `lines` lines.
std::vector<std::string> wrap_words(std::string_view text, std::size_t width, std::size_t lines);

}  // namespace calbox::firmware
