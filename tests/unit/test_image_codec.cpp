// The box's PNG and JPEG reader and writers (core/vision/image_codec.hpp) against OpenCV's
// imgcodecs, the reader and writer they stand in for: the same pixels read from OpenCV's sample
// photos, the same bytes written, the same EXIF turns.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/vision/image_codec.hpp"

namespace fs = std::filesystem;
using namespace calbox;

namespace {

const fs::path kSamples = "/usr/share/doc/opencv-doc/examples/data";

std::vector<std::uint8_t> file_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Pixel for pixel, or a line naming the first difference.
std::string differs(const vision::GrayPixels& ours, const cv::Mat& theirs) {
    if (theirs.type() != CV_8UC1 || ours.width_px != theirs.cols || ours.height_px != theirs.rows)
        return "size " + std::to_string(ours.width_px) + "x" + std::to_string(ours.height_px) +
               " against OpenCV's " + std::to_string(theirs.cols) + "x" +
               std::to_string(theirs.rows);
    for (int y = 0; y < theirs.rows; ++y)
        for (int x = 0; x < theirs.cols; ++x)
            if (ours.pixels[static_cast<std::size_t>(y) * ours.width_px + x] !=
                theirs.at<std::uint8_t>(y, x))
                return "pixel " + std::to_string(x) + "," + std::to_string(y);
    return {};
}

vision::PixelRows rows_of(const cv::Mat& m) {
    return {m.data, m.cols, m.rows, static_cast<int>(m.step[0]), m.channels()};
}

// A photo-like picture: smooth shading, edges and noise (the test's own draws).
cv::Mat scene(int channels) {
    cv::Mat m(181, 243, CV_8UC(channels));
    std::mt19937 draws(5);
    std::uniform_int_distribution<int> noise(-6, 6);
    for (int y = 0; y < m.rows; ++y)
        for (int x = 0; x < m.cols; ++x)
            for (int c = 0; c < channels; ++c) {
                const int edge = ((x / 20 + y / 15) % 2) * 90;
                m.ptr<std::uint8_t>(y)[channels * x + c] = cv::saturate_cast<std::uint8_t>(
                    40 + x / 3 + y / 4 + 30 * c + edge + noise(draws));
            }
    return m;
}

// A JPEG with an EXIF segment whose first directory holds only the orientation tag.
std::vector<std::uint8_t> with_orientation(const std::vector<std::uint8_t>& jpeg, int value,
                                           bool big_endian) {
    std::vector<std::uint8_t> tiff =
        big_endian ? std::vector<std::uint8_t>{'M',  'M',  0, 42, 0,
                                               0,    0,    8, 0,  1,
                                               0x01, 0x12, 0, 3,  0,
                                               0,    0,    1, 0,  static_cast<std::uint8_t>(value),
                                               0,    0,    0, 0,  0,
                                               0}
                   : std::vector<std::uint8_t>{'I',
                                               'I',
                                               42,
                                               0,
                                               8,
                                               0,
                                               0,
                                               0,
                                               1,
                                               0,
                                               0x12,
                                               0x01,
                                               3,
                                               0,
                                               1,
                                               0,
                                               0,
                                               0,
                                               static_cast<std::uint8_t>(value),
                                               0,
                                               0,
                                               0,
                                               0,
                                               0,
                                               0,
                                               0};
    // Laid out in place (GCC 12 at -O3 mistakes vector inserts here for overruns).
    const std::size_t length = 8 + tiff.size();  // the segment's length field counts itself
    std::vector<std::uint8_t> out(jpeg.size() + 2 + length);
    std::copy_n(jpeg.begin(), 2, out.begin());
    const std::uint8_t head[] = {0xFF,
                                 0xE1,
                                 static_cast<std::uint8_t>(length >> 8),
                                 static_cast<std::uint8_t>(length & 0xFF),
                                 'E',
                                 'x',
                                 'i',
                                 'f',
                                 0,
                                 0};
    std::copy(std::begin(head), std::end(head), out.begin() + 2);
    std::copy(tiff.begin(), tiff.end(), out.begin() + 12);
    std::copy(jpeg.begin() + 2, jpeg.end(), out.begin() + 12 + static_cast<long>(tiff.size()));
    return out;
}

}  // namespace

TEST_GROUP(ImageCodec){};

TEST(ImageCodec, opencvs_sample_photos_read_as_opencv_reads_them) {
    int read = 0, colour = 0, png = 0;
    for (const auto& entry : fs::directory_iterator(kSamples)) {
        const auto ext = entry.path().extension().string();
        if (ext != ".jpg" && ext != ".png") continue;
        const auto bytes = file_bytes(entry.path());
        const cv::Mat theirs = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
        if (theirs.empty()) continue;
        const auto ours = vision::decode_gray(bytes);
        const auto difference = differs(ours, theirs);
        CHECK_TEXT(difference.empty(), (entry.path().string() + ": " + difference).c_str());
        ++read;
        colour += cv::imdecode(bytes, cv::IMREAD_UNCHANGED).channels() > 1;
        png += ext == ".png";
    }
    // The package's samples: colour and gray, PNG (palette, alpha, 16-bit among them) and JPEG.
    CHECK_TEXT(read > 60, std::to_string(read).c_str());
    CHECK(colour > 40);
    CHECK(png > 20);
}

TEST(ImageCodec, png_and_jpeg_are_written_byte_for_byte_as_opencv_writes_them) {
    for (const int channels : {1, 3}) {
        const cv::Mat image = scene(channels);
        std::vector<std::uint8_t> theirs;
        CHECK(cv::imencode(".png", image, theirs));
        CHECK(vision::png_bytes(rows_of(image)) == theirs);
        for (const int quality : {68, 80, 93}) {
            CHECK(cv::imencode(".jpg", image, theirs, {cv::IMWRITE_JPEG_QUALITY, quality}));
            CHECK_TEXT(
                vision::jpeg_bytes(rows_of(image), quality) == theirs,
                (std::to_string(channels) + " channels at " + std::to_string(quality)).c_str());
        }
    }
    // A region of a larger picture: its rows lie a whole row of the larger apart.
    const cv::Mat large = scene(1);
    const cv::Mat part = large(cv::Rect(10, 20, 101, 57));
    std::vector<std::uint8_t> theirs;
    CHECK(cv::imencode(".png", part, theirs));
    CHECK(vision::png_bytes(rows_of(part)) == theirs);
    CHECK_THROWS(vision::ImageCodecError, vision::jpeg_bytes(rows_of(part), 0));
    CHECK_THROWS(vision::ImageCodecError, vision::png_bytes({nullptr, 10, 10, 10, 1}));
}

TEST(ImageCodec, exif_orientations_turn_the_picture_as_opencv_turns_it) {
    std::vector<std::uint8_t> plain;
    CHECK(cv::imencode(".jpg", scene(1), plain, {cv::IMWRITE_JPEG_QUALITY, 90}));
    for (const bool big_endian : {false, true})
        for (int value = 1; value <= 8; ++value) {
            const auto turned = with_orientation(plain, value, big_endian);
            const cv::Mat theirs = cv::imdecode(turned, cv::IMREAD_GRAYSCALE);
            const auto difference = differs(vision::decode_gray(turned), theirs);
            CHECK_TEXT(difference.empty(),
                       ("orientation " + std::to_string(value) + ": " + difference).c_str());
        }
    // Turned a quarter: the picture is as tall as it was wide.
    const auto quarter = vision::decode_gray(with_orientation(plain, 6, false));
    CHECK_EQUAL(243, quarter.height_px);
    CHECK_EQUAL(181, quarter.width_px);
}

TEST(ImageCodec, damaged_or_foreign_files_are_refused_with_the_reason) {
    std::vector<std::uint8_t> jpeg;
    CHECK(cv::imencode(".jpg", scene(1), jpeg, {cv::IMWRITE_JPEG_QUALITY, 90}));
    // Bytes of the picture's data overwritten with a marker: OpenCV decodes the rest as grey
    // and says so only on standard error; the box's reader refuses.
    auto damaged = jpeg;
    for (std::size_t i = damaged.size() / 2; i < damaged.size() / 2 + 40; ++i) damaged[i] = 0xFF;
    damaged[damaged.size() / 2 + 40] = 0xD0;
    try {
        vision::decode_gray(damaged);
        FAIL("a damaged JPEG was read");
    } catch (const vision::ImageCodecError& e) {
        STRCMP_CONTAINS("a damaged JPEG: Corrupt JPEG data", e.what());
    }
    const std::string bmp = "BM not a photo";
    try {
        vision::decode_gray({reinterpret_cast<const std::uint8_t*>(bmp.data()), bmp.size()});
        FAIL("a BMP was read");
    } catch (const vision::ImageCodecError& e) {
        STRCMP_EQUAL("neither a PNG nor a JPEG", e.what());
    }
    std::vector<std::uint8_t> png;
    CHECK(cv::imencode(".png", scene(1), png));
    png.resize(png.size() / 2);
    try {
        vision::decode_gray(png);
        FAIL("half a PNG was read");
    } catch (const vision::ImageCodecError& e) {
        STRCMP_CONTAINS("not a PNG the reader takes: ", e.what());
    }
    // Padding after a JPEG's end (some cameras write it) loses nothing.
    std::vector<std::uint8_t> padded(jpeg.size() + 3, 0);
    std::copy(jpeg.begin(), jpeg.end() - 2, padded.begin());
    std::copy(jpeg.end() - 2, jpeg.end(), padded.end() - 2);
    CHECK(differs(vision::decode_gray(padded), cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE)).empty());
}
