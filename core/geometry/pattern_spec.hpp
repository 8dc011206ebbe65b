#pragma once
// Calibration board descriptions as written on the command line:
//   chessboard:COLSxROWS@SQUARE_MM            inner corners, as OpenCV counts them
//   charuco:COLSxROWS@SQUARE_MM/MARKER_MM:DICT squares, e.g. charuco:5x7@40/20:DICT_6X6_250
#include <stdexcept>
#include <string>
#include <string_view>

namespace calbox::geometry {

class PatternError : public std::invalid_argument {
  public:
    using std::invalid_argument::invalid_argument;
};

struct PatternSpec {
    enum class Kind { chessboard, charuco } kind = Kind::chessboard;
    int columns = 0;  // chessboard: inner corners; charuco: squares
    int rows = 0;
    double square_mm = 0;
    double marker_mm = 0;    // charuco only
    std::string dictionary;  // charuco only, OpenCV's name such as DICT_6X6_250
};

// Throws PatternError with a message that shows the expected form.
PatternSpec parse_pattern_spec(std::string_view text);

// The OpenCV predefined dictionary id for a name such as "DICT_6X6_250"; throws PatternError.
int aruco_dictionary_id(std::string_view name);

}  // namespace calbox::geometry
