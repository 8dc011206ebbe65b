#pragma once
// What the tests of other people's inputs (test_realworld*.cpp) share: their photo sets calibrated,
// and G-code files read by their own frame.
#include <CppUTest/TestHarness.h>
#include <fnmatch.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "core/drawings/drawing.hpp"
#include "core/geometry/calibration.hpp"
#include "core/jobs/compensate.hpp"
#include "core/gcode/gcode_line.hpp"
#include "core/jobs/job.hpp"
#include "core/models/machine_file.hpp"
#include "core/models/machine_import.hpp"
#include "core/modes/delta_probe.hpp"
#include "core/modes/record_error.hpp"
#include "core/number_text.hpp"
#include "core/vision/image_codec.hpp"
#include "tests/support/gcode_reference.hpp"
#include "tests/support/test_data.hpp"

using namespace calbox;

namespace realworld_inputs {

struct PhotoSet {
    std::vector<cv::Mat> images;
    std::vector<geometry::NamedImage> named;
};

inline PhotoSet photos_in(const std::string& folder) {
    std::vector<std::string> paths;
    for (const auto& e : std::filesystem::directory_iterator(test::test_data_path(folder)))
        if (e.path().extension() == ".jpg") paths.push_back(e.path().string());
    std::sort(paths.begin(), paths.end());
    PhotoSet set;
    for (const auto& p : paths) set.images.push_back(cv::imread(p, cv::IMREAD_GRAYSCALE));
    for (std::size_t i = 0; i < paths.size(); ++i) {
        const cv::Mat& m = set.images[i];
        set.named.push_back({std::filesystem::path(paths[i]).filename().string(),
                             {m.data, m.cols, m.rows, static_cast<int>(m.step)}});
    }
    return set;
}

// BoofCV's sets: chessboards of 5 x 7 squares (4 x 6 inner corners), 30 mm (the fisheye's in
// units of one square, which scales only the poses).
inline const geometry::PatternSpec kBoofBoard = geometry::parse_pattern_spec("chessboard:4x6@30");

inline geometry::CalibrationResult calibrate(const std::string& folder, geometry::LensModel model) {
    const auto set = photos_in("realworld/camera_calib/" + folder);
    return geometry::calibrate_camera(kBoofBoard, model, set.named);
}

inline void print(const char* what, const geometry::CalibrationResult& r) {
    const auto& c = r.camera;
    UT_PRINT((std::string(what) + ": fx " + std::to_string(c.fx()) + " fy " +
              std::to_string(c.fy()) + " cx " + std::to_string(c.cx()) + " cy " +
              std::to_string(c.cy()) + ", RMS " + std::to_string(c.rms_px) + " px over " +
              std::to_string(r.views.size()) + " views, " + std::to_string(r.dropped.size()) +
              " dropped")
                 .c_str());
}

}  // namespace realworld_inputs

namespace realworld_inputs {

inline const jobs::Correction kSlightlyOff = [](geometry::Point2 p) {
    return geometry::Point2{1.001 * p.x + 0.0005 * p.y + 0.1, -0.0004 * p.x + 0.999 * p.y - 0.05};
};

// Each file in its controller's flavour, its work zero at `work_zero_mm` on the machine, no
// travel limit, the correction everywhere.
inline jobs::JobFrame frame_of_file(const std::string& file, geometry::Point2 work_zero_mm = {}) {
    const bool printer = file.rfind("printer/", 0) == 0;
    const bool ngc = file.size() > 4 && file.substr(file.size() - 4) == ".ngc";
    return {
        printer ? jobs::Flavour::printer : (ngc ? jobs::Flavour::linuxcnc : jobs::Flavour::grbl),
        {work_zero_mm},
        {},
        {}};
}

// A line the compensator moves: one with X or Y (or an arc's words) under a motion command.
// Everything else must come out as it went in, in order (line numbers aside).
inline bool is_xy_motion(const std::string& raw) {
    gcode::Line line;
    try {
        line = gcode::parse_line(raw);
    } catch (const gcode::SyntaxError&) {
        return false;
    }
    if (line.command_letter == 'M' || line.command_letter == 'T') return false;
    for (const int g : {4, 10, 28, 30, 53, 92})
        if (line.is('G', g)) return false;
    if (line.command_letter == 'G' && line.command_subcode >= 0) return false;
    return line.has('X') || line.has('Y') || line.has('I') || line.has('J') || line.has('R');
}

inline std::string without_number(std::string raw) {
    while (!raw.empty() && (raw.back() == '\r' || raw.back() == ' ')) raw.pop_back();
    raw = std::string(gcode::without_checksum(raw));
    std::size_t i = raw.find_first_not_of(" \t");
    if (i != std::string::npos && (raw[i] == 'N' || raw[i] == 'n')) {
        ++i;
        while (i < raw.size() && std::isdigit(static_cast<unsigned char>(raw[i]))) ++i;
        while (i < raw.size() && raw[i] == ' ') ++i;
        raw = raw.substr(i);
    }
    while (!raw.empty() && raw.back() == ' ') raw.pop_back();
    return raw;
}

inline std::vector<std::string> kept_lines(const std::string& text, bool output) {
    std::vector<std::string> kept;
    std::istringstream in(text);
    for (std::string raw; std::getline(in, raw);) {
        if (output) {
            const auto line = gcode::parse_line(raw);
            const bool written_move =
                (line.is('G', 0) || line.is('G', 1) ||
                 (line.command_letter == 'G' && !line.parameters.empty() &&
                  std::any_of(line.parameters.begin(), line.parameters.end(),
                              [](const gcode::Word& w) {
                                  return w.letter == 'G' && w.value && *w.value <= 1;
                              }))) &&
                (line.has('X') || line.has('Y'));
            if (written_move) continue;
        } else if (is_xy_motion(raw)) {
            continue;
        }
        kept.push_back(without_number(raw));
    }
    return kept;
}

}  // namespace realworld_inputs

using namespace realworld_inputs;
