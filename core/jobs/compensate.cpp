#include "core/jobs/compensate.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>
#include <vector>

#include "core/jobs/compensator.hpp"
#include "core/jobs/cutter_path.hpp"
#include "core/number_text.hpp"

namespace calbox::jobs {
namespace compensating {

// No slicer or CAM program writes a line near this (PrusaSlicer's longest, its settings and
// thumbnail lines, stay under a few thousand characters); past it the file is not G-code.
constexpr std::size_t kLongestLine = 65536;

Compensator::Compensator(const MachineCorrection& correction, const JobFrame& frame,
                         const CompensateSettings& settings, CompensateReport& report)
    : correction_(correction), frame_(frame), settings_(settings), report_(report) {
    m_.work_zero_mm = frame.work_zero_mm;
    // grbl powers up in G0: axis words alone move. LinuxCNC and printers start with none.
    if (frame.flavour == Flavour::grbl) m_.motion = 0;
    if (frame.start_mm) {
        m_.xy_mm = *frame.start_mm;
        m_.xy_known = true;
        if (const auto offset = m_.offset_mm()) m_.written_xy = job_of(*frame.start_mm, *offset);
    }
}

std::vector<std::pair<std::string, long>> Compensator::job_lines(std::string_view job) {
    std::vector<std::pair<std::string, long>> lines;
    if (gcode::uses_ngc_language(job)) {
        report_.ran_program = true;
        try {
            for (auto& l : gcode::run_ngc_program(job, settings_.program))
                lines.emplace_back(std::move(l.text), l.source_line);
        } catch (const gcode::ProgramError& e) {
            throw CompensateError(e.what());
        }
        return lines;
    }
    long number = 0;
    for (const std::string_view raw : gcode::lines_of_job(job)) {
        ++number;
        if (raw.size() > kLongestLine)
            throw CompensateError("line " + std::to_string(number) + " is " +
                                  std::to_string(raw.size()) +
                                  " characters long: not G-code (a line holds at most " +
                                  std::to_string(kLongestLine) + ")");
        lines.emplace_back(std::string(raw), number);
    }
    return lines;
}

std::string Compensator::run(std::string_view job) {
    auto lines = job_lines(job);
    // A lathe job is refused as one, wherever its first lathe word stands; and the file's
    // written precision is the most decimals its coordinates carry.
    int decimals = 0;
    bool ended = false, cutter_compensated = false;
    for (const auto& [raw, number] : lines) {
        gcode::Line parsed;
        try {
            // E too: LinuxCNC's G76 threading has one, and the lathe job is refused as one.
            const std::string text = words_of(raw, nullptr, "E");
            decimals = std::max(decimals, written_decimals(text, "XYZIJKR"));
            parsed = gcode::parse_line(text);
            ended = ended || has_m(parsed, 2) || has_m(parsed, 30) ||
                    (gcode::strip_comments(raw).empty() && raw.find('%') != std::string::npos);
            for (const Code c : g_codes_of(parsed)) {
                if (c.number == 41 || c.number == 42) cutter_compensated = true;
                if (is_lathe_word(c)) {
                    line_number_ = number;
                    throw fail(refused_word(c, parsed, frame_.flavour));
                }
            }
        } catch (const gcode::SyntaxError&) {
            continue;  // named where the line is read
        }
    }
    if (frame_.flavour == Flavour::linuxcnc && !ended && !lines.empty()) {
        line_number_ = lines.back().second;
        throw fail(
            "the job ends without M2, M30 or a closing '%': LinuxCNC stops on it (\"File "
            "ended with no percent sign or program end\"); end it with M2");
    }
    written_precision_ = std::pow(10.0, -std::min(decimals, 6));
    if (frame_.flavour == Flavour::linuxcnc && cutter_compensated)
        lines = cutter_path(lines, settings_.tool_radius_mm,
                            [this](const std::string& raw, long number) {
                                line_number_ = number;
                                Polar polar;
                                ReadLine r;
                                r.line = gcode::parse_line(words_of(raw, &polar));
                                r.codes = g_codes_of(r.line);
                                r.polar = polar.any();
                                // What the path's lines are written from keeps LinuxCNC's word
                                // rules.
                                word_rules(r.line, r.codes);
                                return r;
                            });
    for (auto& [raw, number] : lines) {
        ++report_.lines;
        line_number_ = number;
        line(raw);
    }
    return std::move(out_);
}

}  // namespace compensating

using compensating::Compensator;
using compensating::held_correction;
using geometry::Point2;
using job_words::number;

Flavour flavour_of_firmware(std::string_view firmware) {
    if (firmware == "marlin" || firmware == "rrf" || firmware == "klipper") return Flavour::printer;
    if (firmware == "grbl") return Flavour::grbl;
    if (firmware == "linuxcnc") return Flavour::linuxcnc;
    throw CompensateError("no job flavour for firmware '" + std::string(firmware) + "'");
}

bool Area::contains(Point2 p) const {
    const double slack = 1e-9;
    return p.x >= min_x_mm - slack && p.x <= max_x_mm + slack && p.y >= min_y_mm - slack &&
           p.y <= max_y_mm + slack;
}

Point2 Area::nearest(Point2 p) const {
    return {std::clamp(p.x, min_x_mm, max_x_mm), std::clamp(p.y, min_y_mm, max_y_mm)};
}

std::string compensate_gcode(std::string_view job, const MachineCorrection& correction,
                             const JobFrame& frame, const CompensateSettings& settings,
                             CompensateReport& report) {
    if (!(settings.max_segment_mm > 0) || !(settings.arc_tolerance_mm > 0))
        throw CompensateError("the segment length and arc tolerance must be positive");
    return Compensator(correction, frame, settings, report).run(job);
}

namespace {

struct ScannerPoint {
    double x_mm, y_mm, power;
};
// A scanner job's "x_mm,y_mm,power" line; throws CompensateError naming the line.
ScannerPoint scanner_point_of(const std::string& raw, long number_of_line) {
    ScannerPoint p{0, 0, 0};
    char tail = 0;
    if (std::sscanf(raw.c_str(), "%lf,%lf,%lf%c", &p.x_mm, &p.y_mm, &p.power, &tail) != 3 ||
        !std::isfinite(p.x_mm) || !std::isfinite(p.y_mm) || !(p.power >= 0 && p.power <= 1))
        throw CompensateError("line " + std::to_string(number_of_line) +
                              ": expected x_mm,y_mm,power with power from 0 to 1");
    return p;
}

// A corrected point's line of the scanner job, in the job's coordinates from `zero`.
std::string scanner_line(Point2 corrected_mm, Point2 zero, double power) {
    char line[128];
    std::snprintf(line, sizeof line, "%.4f,%.4f,%s\n", corrected_mm.x - zero.x,
                  corrected_mm.y - zero.y, number(power, 3).c_str());
    return line;
}

// Where the scanner job's zero lies in the field; throws CompensateError where the job cannot be
// placed so (no zero, a turned or scaled frame) or the segment length is not positive.
Point2 scanner_zero_of(const JobFrame& frame, const CompensateSettings& settings) {
    if (!(settings.max_segment_mm > 0))
        throw CompensateError("the segment length must be positive");
    if (!frame.work_zero_mm[0])
        throw CompensateError("the scanner job's zero on the machine is not known");
    if (frame.turn_rad != 0 || frame.scale != 1)
        throw CompensateError("a scanner job is not placed turned: its field is the machine's");
    return *frame.work_zero_mm[0];
}

}  // namespace

std::string compensate_scanner_csv(std::string_view job, const MachineCorrection& correction,
                                   const JobFrame& frame, const CompensateSettings& settings,
                                   CompensateReport& report) {
    const Point2 zero = scanner_zero_of(frame, settings);
    std::istringstream in{std::string(job)};
    std::string raw, out;
    long number_of_line = 0;
    std::optional<Point2> at;
    while (std::getline(in, raw)) {
        ++number_of_line;
        ++report.lines;
        if (!raw.empty() && raw.back() == '\r') raw.pop_back();
        if (number_of_line == 1) {
            if (raw != "x_mm,y_mm,power")
                throw CompensateError(
                    "line 1: a scanner job starts with the header x_mm,y_mm,power");
            out += raw + '\n';
            continue;
        }
        if (raw.empty() || raw[0] == '#') {
            out += raw + '\n';
            continue;
        }
        const auto [x, y, power] = scanner_point_of(raw, number_of_line);
        const Point2 to{x + zero.x, y + zero.y};
        if (!frame.travel_mm.contains(to))
            throw CompensateError("line " + std::to_string(number_of_line) + ": the point " +
                                  number(x, 4) + "," + number(y, 4) +
                                  " is beyond the field the machine reaches");
        ++report.moves;
        // Burning, the move is cut so that the correction follows the field along it; a jump
        // goes straight to its end.
        const int pieces =
            power > 0 && at
                ? std::max(1, static_cast<int>(std::ceil(std::hypot(to.x - at->x, to.y - at->y) /
                                                         settings.max_segment_mm)))
                : 1;
        for (int k = 1; k <= pieces; ++k) {
            const Point2 p = k == pieces ? to
                                         : Point2{at->x + (to.x - at->x) * k / pieces,
                                                  at->y + (to.y - at->y) * k / pieces};
            out += scanner_line(held_correction(correction, p, report), zero, power);
            ++report.pieces;
        }
        at = to;
    }
    if (number_of_line == 0) throw CompensateError("the scanner job is empty");
    return out;
}

namespace {
constexpr std::string_view kMarkStart = "calbox: compensated through result ";
}  // namespace

std::string compensated_mark(std::string_view result_digest, std::string_view date) {
    std::string mark(kMarkStart);
    mark += result_digest;
    mark += " on ";
    mark += date;
    return mark;
}

std::string compensated_mark_in(std::string_view job) {
    const auto at = job.find(kMarkStart);
    if (at == std::string_view::npos) return {};
    const auto end = job.find_first_of("\r\n)", at);
    return std::string(job.substr(at, end == std::string_view::npos ? end : end - at));
}

std::string with_compensated_mark(std::string_view job, std::string_view mark) {
    if (job.rfind("x_mm,y_mm,power", 0) == 0) {
        const auto end = job.find('\n');
        if (end == std::string_view::npos)
            return std::string(job) + "\n# " + std::string(mark) + "\n";
        return std::string(job.substr(0, end + 1)) + "# " + std::string(mark) + "\n" +
               std::string(job.substr(end + 1));
    }
    // A program's opening '%' stays its first line.
    std::size_t first = 0;
    const auto end = job.find('\n');
    const std::string_view opening = job.substr(0, end);
    if (opening.find_first_not_of(" \t\r") != std::string_view::npos &&
        opening.substr(opening.find_first_not_of(" \t\r"), 1) == "%" &&
        opening.find_first_not_of(" \t\r%") == std::string_view::npos)
        first = end == std::string_view::npos ? job.size() : end + 1;
    std::string out(job.substr(0, first));
    if (first == job.size() && !out.empty() && out.back() != '\n') out += '\n';
    out += "; " + std::string(mark) + "\n";
    out += job.substr(first);
    return out;
}

}  // namespace calbox::jobs
