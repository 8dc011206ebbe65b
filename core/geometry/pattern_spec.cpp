#include "core/geometry/pattern_spec.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <utility>

namespace calbox::geometry {
namespace {

constexpr std::string_view kForms =
    "expected chessboard:COLSxROWS@SQUARE_MM, charuco:COLSxROWS@SQUARE_MM/MARKER_MM:DICT, "
    "aruco:COLSxROWS@MARKER_MM/GAP_MM:DICT, circles:COLSxROWS@PITCH_MM or "
    "acircles:COLSxROWS@PITCH_MM";

[[noreturn]] void fail(std::string_view text, std::string_view why) {
    throw PatternError("bad pattern '" + std::string(text) + "': " + std::string(why) + " (" +
                       std::string(kForms) + ")");
}

// Built by appending: GCC 12 at -O3 misreports "'" + std::string(...) (-Wrestrict, PR105329).
std::string quoted(std::string_view s) {
    std::string out;
    out.reserve(s.size() + 2);
    out.push_back('\'');
    out.append(s);
    out.push_back('\'');
    return out;
}

int parse_count(std::string_view whole, std::string_view s) {
    int v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || end != s.data() + s.size() || v < 2 || v > 200) {
        fail(whole, quoted(s) + " is not a count from 2 to 200");
    }
    return v;
}

double parse_length(std::string_view whole, std::string_view s) {
    double v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v) || v <= 0) {
        fail(whole, quoted(s) + " is not a positive length in mm");
    }
    return v;
}

}  // namespace

int aruco_dictionary_id(std::string_view name) {
    // OpenCV's PREDEFINED_DICTIONARY_NAME enumeration order.
    static constexpr std::array<std::string_view, 21> kNames{
        "DICT_4X4_50",         "DICT_4X4_100",       "DICT_4X4_250",       "DICT_4X4_1000",
        "DICT_5X5_50",         "DICT_5X5_100",       "DICT_5X5_250",       "DICT_5X5_1000",
        "DICT_6X6_50",         "DICT_6X6_100",       "DICT_6X6_250",       "DICT_6X6_1000",
        "DICT_7X7_50",         "DICT_7X7_100",       "DICT_7X7_250",       "DICT_7X7_1000",
        "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_16h5", "DICT_APRILTAG_25h9", "DICT_APRILTAG_36h10",
        "DICT_APRILTAG_36h11"};
    for (std::size_t i = 0; i < kNames.size(); ++i)
        if (kNames[i] == name) return static_cast<int>(i);
    throw PatternError("unknown ArUco dictionary '" + std::string(name) +
                       "' (names such as DICT_4X4_50 ... DICT_7X7_1000, DICT_ARUCO_ORIGINAL, "
                       "DICT_APRILTAG_36h11)");
}

PatternSpec parse_pattern_spec(std::string_view text) {
    PatternSpec spec;
    const auto colon = text.find(':');
    if (colon == std::string_view::npos) fail(text, "no kind");
    const auto kind = text.substr(0, colon);
    std::string_view rest = text.substr(colon + 1);
    if (kind == "chessboard") {
        spec.kind = PatternSpec::Kind::chessboard;
    } else if (kind == "circles") {
        spec.kind = PatternSpec::Kind::circles;
    } else if (kind == "acircles") {
        spec.kind = PatternSpec::Kind::acircles;
    } else if (kind == "charuco" || kind == "aruco") {
        spec.kind = kind == "charuco" ? PatternSpec::Kind::charuco : PatternSpec::Kind::aruco;
        const auto dict_colon = rest.rfind(':');
        if (dict_colon == std::string_view::npos) fail(text, "no dictionary");
        spec.dictionary = std::string(rest.substr(dict_colon + 1));
        aruco_dictionary_id(spec.dictionary);
        rest = rest.substr(0, dict_colon);
    } else {
        fail(text, "unknown kind '" + std::string(kind) + "'");
    }
    const auto at = rest.find('@');
    const auto x = rest.find('x');
    if (at == std::string_view::npos || x == std::string_view::npos || x > at) {
        fail(text, "size must read COLSxROWS@MM");
    }
    spec.columns = parse_count(text, rest.substr(0, x));
    spec.rows = parse_count(text, rest.substr(x + 1, at - x - 1));
    std::string_view lengths = rest.substr(at + 1);
    if (spec.kind == PatternSpec::Kind::charuco) {
        const auto slash = lengths.find('/');
        if (slash == std::string_view::npos) fail(text, "charuco needs SQUARE_MM/MARKER_MM");
        spec.square_mm = parse_length(text, lengths.substr(0, slash));
        spec.marker_mm = parse_length(text, lengths.substr(slash + 1));
        if (spec.marker_mm >= spec.square_mm)
            fail(text, "the marker must be smaller than the square");
    } else if (spec.kind == PatternSpec::Kind::aruco) {
        const auto slash = lengths.find('/');
        if (slash == std::string_view::npos) fail(text, "aruco needs MARKER_MM/GAP_MM");
        spec.marker_mm = parse_length(text, lengths.substr(0, slash));
        spec.gap_mm = parse_length(text, lengths.substr(slash + 1));
    } else {
        spec.square_mm = parse_length(text, lengths);
    }
    return spec;
}

}  // namespace calbox::geometry
