// The display's font and screens. The README's pictures (docs/screens/*.png) are these
// drawings: the test compares them pixel for pixel, and CALBOX_WRITE_SCREENS=1 rewrites them.
#include <CppUTest/TestHarness.h>

#include <cstdlib>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "firmware/cycle/screens.hpp"

using namespace calbox;
using firmware::draw_screen;

namespace {

int lit_in_row(const hal::MonoBitmap& b, int y, int x0, int x1) {
    int n = 0;
    for (int x = x0; x < x1; ++x) n += b.at(x, y) ? 1 : 0;
    return n;
}

constexpr int kScale = 3;  // the README's pictures: three screen pixels a pixel

cv::Mat picture(const hal::MonoBitmap& b) {
    cv::Mat small(b.height_px(), b.width_px(), CV_8UC1);
    for (int y = 0; y < b.height_px(); ++y)
        for (int x = 0; x < b.width_px(); ++x) small.at<std::uint8_t>(y, x) = b.at(x, y) ? 255 : 0;
    cv::Mat big;
    cv::resize(small, big, {}, kScale, kScale, cv::INTER_NEAREST);
    return big;
}

}  // namespace

TEST_GROUP(Font){};

TEST(Font, draws_terminus_glyphs_where_they_belong) {
    hal::MonoBitmap b(128, 64);
    firmware::draw_text(b, 10, 20, "A");
    // Terminus 6x12 'A', worked out from its rows: a top bar of three pixels on row 2, the sides
    // on rows 3..9, the crossbar of five on row 6, nothing on rows 0, 1, 10 and 11.
    for (int x = 10; x < 16; ++x) {
        CHECK_FALSE(b.at(x, 20));
        CHECK_FALSE(b.at(x, 21));
        CHECK_FALSE(b.at(x, 30));
    }
    CHECK_EQUAL(3, lit_in_row(b, 22, 10, 16));
    CHECK_TRUE(b.at(11, 22) && b.at(12, 22) && b.at(13, 22));
    CHECK_EQUAL(5, lit_in_row(b, 26, 10, 16));
    CHECK_TRUE(b.at(10, 25) && b.at(14, 25) && !b.at(12, 25));
    CHECK_FALSE(b.at(15, 26));  // the sixth column is the gap between letters

    // Inverted: the same glyph dark on a lit cell; outside ASCII: '?'; past the edge: clipped.
    hal::MonoBitmap inverted(128, 64), question(128, 64), unknown(128, 64);
    firmware::draw_text(inverted, 10, 20, "A", true);
    for (int y = 20; y < 32; ++y)
        for (int x = 10; x < 16; ++x) CHECK_EQUAL(!b.at(x, y), inverted.at(x, y));
    firmware::draw_text(question, 0, 0, "?");
    firmware::draw_text(unknown, 0, 0, "\xb5");
    CHECK_TRUE(question == unknown);
    hal::MonoBitmap edge(128, 64);
    firmware::draw_text(edge, 125, 60, "WWW");  // 'W''s left stroke starts on its row 2
    CHECK_TRUE(edge.at(125, 62) && edge.at(125, 63));
    CHECK_EQUAL(0, lit_in_row(edge, 61, 0, 128));
}

TEST(Font, wraps_words_over_the_displays_lines) {
    const auto lines = firmware::wrap_words("hold the whole board in view, press", 21, 2);
    CHECK_EQUAL(2U, lines.size());
    STRCMP_EQUAL("hold the whole board", lines[0].c_str());
    STRCMP_EQUAL("in view, press", lines[1].c_str());
    CHECK_EQUAL(1U, firmware::wrap_words("a", 21, 2).size());
    const auto cut = firmware::wrap_words("abcdefghijklmnopqrstuvwxyz one", 21, 3);
    STRCMP_EQUAL("abcdefghijklmnopqrstu", cut[0].c_str());  // a longer word is cut
    CHECK_EQUAL(0U, firmware::wrap_words("   ", 21, 2).size());
}

TEST_GROUP(Screens){};

TEST(Screens, the_progress_bar_fills_to_its_fraction_and_the_title_is_inverted) {
    const auto half = draw_screen(firmware::ProgressScreen{"measure", 0.5, 42, "143 holes"});
    CHECK_TRUE(half.at(0, 0) && half.at(127, 11));  // the title bar is lit
    // The bar's inside row (y 13 + 5): lit from x 2 to 2 + 62 (half of 123 rounded), then not.
    CHECK_TRUE(half.at(2, 18) && half.at(63, 18));
    CHECK_FALSE(half.at(65, 18));
    CHECK_FALSE(half.at(120, 18));
    const auto full = draw_screen(firmware::ProgressScreen{"verify", 1.0, {}, ""});
    CHECK_TRUE(full.at(124, 18));
    CHECK_FALSE(full == draw_screen(firmware::ProgressScreen{"verify", 0.9, {}, ""}));
}

TEST(Screens, the_readmes_pictures_are_these_drawings) {
    const std::filesystem::path dir = std::filesystem::path(CALBOX_SOURCE_DIR) / "docs" / "screens";
    const std::pair<const char*, hal::MonoBitmap> screens[] = {
        {"idle",
         draw_screen(firmware::IdleScreen{"delta Marlin", "last 0.257->0.003 mm", "goal met"})},
        {"setup", draw_screen(firmware::PromptScreen{
                      "set-up: camera", "hold the board in view, press", "view 5/12", 0.62})},
        {"progress",
         draw_screen(firmware::ProgressScreen{"measure", 0.375, 48, "measuring 1 photo(s)"})},
        {"review", draw_screen(firmware::ReviewScreen{
                       {"rod +1.144 mm", "radius -0.512 mm"}, "XY 0.257", "0.003 mm"})},
        {"done", draw_screen(firmware::DoneScreen{"0.2574 mm", "0.0032 mm"})},
        {"error", draw_screen(firmware::ErrorScreen{4, "check camera + light",
                                                    "camera: frame 2 of 3 never arrived "
                                                    "(sensor timeout)"})},
        {"network", draw_screen(firmware::NetworkScreen{
                        8443,
                        {"9428 2900 8663 E6BB", "ADD0 D3BB E394 799E", "AC53 62CB 34D6 1DF4",
                         "EAEE 82C0 D3BF C846"}})},
    };
    const bool write = std::getenv("CALBOX_WRITE_SCREENS") != nullptr;
    for (const auto& [name, bitmap] : screens) {
        const auto path = dir / (std::string(name) + ".png");
        if (write) cv::imwrite(path.string(), picture(bitmap));
        const cv::Mat stored = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
        CHECK_TRUE_TEXT(!stored.empty(), (path.string() + " is missing").c_str());
        CHECK_EQUAL_TEXT(0, cv::norm(stored, picture(bitmap), cv::NORM_INF),
                         (path.string() + " is not what the code draws").c_str());
    }
}
