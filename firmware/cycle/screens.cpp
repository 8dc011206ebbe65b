#include "firmware/cycle/screens.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>

namespace calbox::firmware {
namespace {

constexpr std::array<std::array<std::uint8_t, 12>, 95> kFont = {{
#include "firmware/cycle/font_6x12.inc"
}};

// A 12 px title, then 13 px per line; a row outside them is a programming error (at() throws).
constexpr std::array<int, 5> kLineTop = {0, 13, 26, 39, 52};

hal::MonoBitmap with_title(std::string_view title) {
    hal::MonoBitmap b(128, 64);
    for (int y = 0; y < 12; ++y)
        for (int x = 0; x < 128; ++x) b.set(x, y, true);
    draw_text(b, 2, 0, title.substr(0, kScreenColumns), true);
    return b;
}

void line(hal::MonoBitmap& b, int row, std::string_view text) {
    draw_text(b, 1, kLineTop.at(static_cast<std::size_t>(row)), text.substr(0, kScreenColumns));
}

// A bar over the line's width, filled to `fraction`.
void bar(hal::MonoBitmap& b, int row, double fraction) {
    const int top = kLineTop.at(static_cast<std::size_t>(row)) + 2,
              bottom = kLineTop.at(static_cast<std::size_t>(row)) + 9;
    const int filled = 2 + static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * 123));
    for (int x = 1; x < 127; ++x) {
        b.set(x, top, true);
        b.set(x, bottom, true);
    }
    for (int y = top; y <= bottom; ++y) {
        b.set(1, y, true);
        b.set(126, y, true);
        for (int x = 2; x < filled; ++x) b.set(x, y, true);
    }
}

std::string percent(double fraction) {
    return std::to_string(static_cast<int>(std::lround(100 * std::clamp(fraction, 0.0, 1.0)))) +
           " %";
}

}  // namespace

void draw_text(hal::MonoBitmap& bitmap, int x, int y, std::string_view text, bool inverted) {
    for (const char c : text) {
        const int code = static_cast<unsigned char>(c);
        const auto& glyph =
            kFont[static_cast<std::size_t>(code >= 32 && code <= 126 ? code - 32 : '?' - 32)];
        for (int row = 0; row < kFontHeightPx; ++row)
            for (int col = 0; col < kFontWidthPx; ++col) {
                const bool ink = (glyph[static_cast<std::size_t>(row)] & (0x80 >> col)) != 0;
                bitmap.set(x + col, y + row, ink != inverted);
            }
        x += kFontWidthPx;
    }
}

std::vector<std::string> wrap_words(std::string_view text, std::size_t width, std::size_t lines) {
    std::vector<std::string> out;
    std::string current;
    std::size_t at = 0;
    while (at < text.size() && out.size() < lines) {
        const auto start = text.find_first_not_of(' ', at);
        if (start == std::string_view::npos) break;
        auto end = text.find(' ', start);
        if (end == std::string_view::npos) end = text.size();
        std::string word(text.substr(start, std::min(end - start, width)));
        at = end;
        if (current.empty()) {
            current = word;
        } else if (current.size() + 1 + word.size() <= width) {
            current += ' ';
            current += word;
        } else {
            out.push_back(current);
            current = word;
        }
    }
    if (!current.empty() && out.size() < lines) out.push_back(current);
    return out;
}

hal::MonoBitmap draw_screen(const IdleScreen& s) {
    auto b = with_title("calbox: ready");
    line(b, 1, s.machine);
    line(b, 2, s.last_result);
    if (!s.verdict.empty()) line(b, 3, s.verdict);
    line(b, 4, "press to calibrate");
    return b;
}

hal::MonoBitmap draw_screen(const ProgressScreen& s) {
    auto b = with_title(s.stage);
    bar(b, 1, s.fraction);
    line(b, 2,
         percent(s.fraction) + (s.seconds_left
                                    ? ", about " + std::to_string(*s.seconds_left) + " s left"
                                    : std::string()));
    const auto detail = wrap_words(s.detail, kScreenColumns, 2);
    for (std::size_t i = 0; i < detail.size(); ++i) line(b, 3 + static_cast<int>(i), detail[i]);
    return b;
}

hal::MonoBitmap draw_screen(const PromptScreen& s) {
    auto b = with_title(s.title);
    const auto words = wrap_words(s.instruction, kScreenColumns, 2);
    for (std::size_t i = 0; i < words.size(); ++i) line(b, 1 + static_cast<int>(i), words[i]);
    if (!s.step.empty())
        line(b, 3, s.step + (s.coverage ? ", " + percent(*s.coverage) + " seen" : std::string()));
    if (s.coverage) bar(b, 4, *s.coverage);
    return b;
}

hal::MonoBitmap draw_screen(const ReviewScreen& s) {
    auto b = with_title("review: apply?");
    for (std::size_t i = 0; i < std::min<std::size_t>(2, s.change.size()); ++i)
        line(b, 1 + static_cast<int>(i), s.change[i]);
    line(b, 3, s.now + " -> " + s.predicted);
    line(b, 4, "press: apply hold: no");
    return b;
}

hal::MonoBitmap draw_screen(const DoneScreen& s) {
    auto b = with_title("done");
    line(b, 1, "before " + s.before);
    line(b, 2, "after  " + s.after);
    line(b, 4, "press to calibrate");
    return b;
}

hal::MonoBitmap draw_screen(const NetworkScreen& s) {
    auto b = with_title("https :" + std::to_string(s.https_port) + " SHA-256");
    for (std::size_t i = 0; i < s.fingerprint.size() && i < 4; ++i)
        line(b, 1 + static_cast<int>(i), s.fingerprint[i]);
    return b;
}

hal::MonoBitmap draw_screen(const ErrorScreen& s) {
    char code[16];
    std::snprintf(code, sizeof code, "E%02d", s.code);
    auto b = with_title(std::string("error ") + code);
    line(b, 1, s.hint);
    const auto words = wrap_words(s.message, kScreenColumns, 2);
    for (std::size_t i = 0; i < words.size(); ++i) line(b, 2 + static_cast<int>(i), words[i]);
    line(b, 4, "press: acknowledge");
    return b;
}

}  // namespace calbox::firmware
