#pragma once
// Board and pattern descriptions as written on the command line:
//   chessboard:COLSxROWS@SQUARE_MM              inner corners, as OpenCV counts them
//   charuco:COLSxROWS@SQUARE_MM/MARKER_MM:DICT  squares, e.g. charuco:5x7@40/20:DICT_6X6_250
//   aruco:COLSxROWS@MARKER_MM/GAP_MM:DICT       a grid of markers (OpenCV's GridBoard)
//   circles:COLSxROWS@PITCH_MM                  a symmetric grid of dark dots
//   acircles:COLSxROWS@PITCH_MM                 an asymmetric grid (OpenCV's convention)
#include <stdexcept>
#include <string>
#include <string_view>

namespace calbox::geometry {

class PatternError : public std::invalid_argument {
  public:
    using std::invalid_argument::invalid_argument;
};

struct PatternSpec {
    enum class Kind { chessboard, charuco, aruco, circles, acircles } kind = Kind::chessboard;
    int columns = 0;  // chessboard: inner corners; charuco: squares; aruco: markers; dots
    int rows = 0;
    double square_mm = 0;    // chessboard and charuco squares; dot pitch
    double marker_mm = 0;    // charuco and aruco
    double gap_mm = 0;       // aruco: space between markers
    std::string dictionary;  // charuco and aruco, OpenCV's name such as DICT_6X6_250

    bool has_markers() const { return kind == Kind::charuco || kind == Kind::aruco; }
    bool is_circles() const { return kind == Kind::circles || kind == Kind::acircles; }
};

// Throws PatternError with a message that shows the expected form.
PatternSpec parse_pattern_spec(std::string_view text);

// The OpenCV predefined dictionary id for a name such as "DICT_6X6_250"; throws PatternError.
int aruco_dictionary_id(std::string_view name);

}  // namespace calbox::geometry
