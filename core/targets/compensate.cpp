#include "core/targets/compensate.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>
#include <vector>

#include "core/targets/gcode_line.hpp"

namespace calbox::targets {
namespace {

using geometry::Point2;

constexpr double kPi = 3.14159265358979323846;
// No slicer or CAM program writes a line near this (PrusaSlicer's longest, its settings and
// thumbnail lines, stay under a few thousand characters); past it the file is not G-code.
constexpr std::size_t kLongestLine = 65536;

// A number as G-code writes it: no exponent, no trailing zeros.
std::string number(double v, int decimals) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.*f", decimals, v);
    std::string s = buffer;
    if (s.find('.') != std::string::npos) {
        while (s.back() == '0') s.pop_back();
        if (s.back() == '.') s.pop_back();
    }
    if (s == "-0") s = "0";
    return s;
}

// The comment part of a raw line (from its first ';' or '('), kept as written.
std::string comment_of(std::string_view raw) {
    const auto at = raw.find_first_of(";(");
    if (at == std::string_view::npos) return {};
    std::string c(raw.substr(at));
    while (!c.empty() && (c.back() == '\r' || c.back() == '\n')) c.pop_back();
    return c;
}

class Writer {
  public:
    Writer(const Correction& correct, const Covers& covers, CompensateReport& report)
        : correct_(correct), covers_(covers), report_(report) {}

    Point2 corrected(Point2 p) {
        if (!covers_(p)) ++report_.outside;
        return correct_(p);
    }

  private:
    const Correction& correct_;
    const Covers& covers_;
    CompensateReport& report_;
};

// A G word's number and its decimal (92.1 -> 92, 1; 90 -> 90, -1).
struct Code {
    int number = -1, subcode = -1;
    bool is(int n) const { return number == n && subcode < 0; }
    bool is_motion() const { return number >= 0 && number <= 3 && subcode < 0; }
    // Appended piece by piece: at -O3 (the release preset) GCC 12 takes `"G" + to_string(...)`
    // for an overlapping copy, and -Werror=restrict stopped the main job's build (GCC bug 105329).
    std::string text() const {
        std::string out = "G";
        out += std::to_string(number);
        if (subcode >= 0) {
            out += '.';
            out += std::to_string(subcode);
        }
        return out;
    }
};

// The line's G words: its command and every G among its words (G90 G94 G17 G21), read as the
// command is. Throws gcode::SyntaxError for a G word that is no command number.
std::vector<Code> g_codes_of(const gcode::Line& line) {
    std::vector<Code> codes;
    if (line.command_letter == 'G') codes.push_back({line.command_number, line.command_subcode});
    for (const auto& w : line.parameters)
        if (w.letter == 'G' && w.value) {
            const auto command = gcode::command_number_of('G', *w.value);
            if (!command) throw gcode::SyntaxError("bad command number after G");
            codes.push_back({command->number, command->subcode});
        }
    return codes;
}

bool has_m(const gcode::Line& line, int number) {
    if (line.is('M', number)) return true;
    for (const auto& w : line.parameters)
        if (w.letter == 'M' && w.value && *w.value == number) return true;
    return false;
}

// What the controller holds between lines, as the job's lines set it. XY are kept on the frame
// the correction was measured on (the job's frame without a G92 offset, G54), in mm; Z in the
// job's own frame, in mm (the correction does not move it; a move's pieces share it).
struct Modal {
    int motion = -1;  // 0..3, or -1 before any motion command and after G80
    bool absolute = true, absolute_e = true;
    double unit_mm = 1;  // 25.4 after G20
    int plane = 17;
    Point2 g92_offset_mm;  // the calibrated frame's point minus the job's, for XY
    Point2 xy_mm;
    bool xy_known = false;  // not until a move gives both axes (and not after G28)
    std::optional<double> z_mm;
    double e = 0;
    // The position last written, in the job's units and frame: relative moves are written as
    // differences of it, so that rounding never accumulates.
    Point2 written_xy;
    std::optional<double> written_z;
};

struct PathPoint {
    Point2 xy;                   // the calibrated frame, mm
    std::optional<double> z_mm;  // the job's frame
};

// A straight move's pieces, from the start (excluded) to the end.
std::vector<PathPoint> line_path(bool start_known, Point2 from, Point2 to,
                                 std::optional<double> z_from, std::optional<double> z_to,
                                 const CompensateSettings& settings) {
    const double length = start_known ? std::hypot(to.x - from.x, to.y - from.y) : 0;
    const int pieces = std::max(1, static_cast<int>(std::ceil(length / settings.max_segment_mm)));
    std::vector<PathPoint> path;
    for (int k = 1; k <= pieces; ++k) {
        const double share = static_cast<double>(k) / pieces;
        std::optional<double> z = z_to;
        if (z_from && z_to) z = *z_from + (*z_to - *z_from) * share;
        path.push_back({k == pieces ? to
                                    : Point2{from.x + (to.x - from.x) * share,
                                             from.y + (to.y - from.y) * share},
                        z});
    }
    return path;
}

template <typename Fail>
std::vector<PathPoint> arc_path(const gcode::Line& line, const Modal& m, Point2 from, Point2 to,
                                std::optional<double> z_from, std::optional<double> z_to,
                                const CompensateSettings& settings, const Fail& fail) {
    if (!m.xy_known) throw fail("an arc needs a known start");
    if (m.plane != 17 && (!z_from || !z_to))
        throw fail("an arc in the XZ or YZ plane needs a known Z");
    // The arc's plane as (a, b) with the helix along h: G17 XY, G18 ZX, G19 YZ, each ordered so
    // that a x b is the plane's normal (clockwise as seen from its positive side).
    const auto to_abh = [&](Point2 xy, double z) -> std::array<double, 3> {
        if (m.plane == 18) return {z, xy.x, xy.y};
        if (m.plane == 19) return {xy.y, z, xy.x};
        return {xy.x, xy.y, z};
    };
    const auto from_abh = [&](const std::array<double, 3>& p) -> PathPoint {
        if (m.plane == 18) return {{p[1], p[2]}, p[0]};
        if (m.plane == 19) return {{p[2], p[0]}, p[1]};
        return {{p[0], p[1]}, p[2]};
    };
    const char offset_a = m.plane == 17 ? 'I' : (m.plane == 18 ? 'K' : 'J');
    const char offset_b = m.plane == 17 ? 'J' : (m.plane == 18 ? 'I' : 'K');
    const auto f = to_abh(from, z_from.value_or(0));
    const auto t = to_abh(to, z_to.value_or(0));
    const bool clockwise = m.motion == 2;
    double ca = 0, cb = 0;
    if (line.has('R')) {
        const double r = line.value('R').value_or(0) * m.unit_mm;
        const double da = t[0] - f[0], db = t[1] - f[1], chord = std::hypot(da, db);
        if (!(std::abs(r) >= chord / 2 - 1e-9) || chord == 0)
            throw fail("the arc's radius R is shorter than half its chord");
        const double h = std::sqrt(std::max(0.0, r * r - chord * chord / 4));
        // Clockwise with R > 0 takes the short way: the centre to the chord's right.
        const double side = (clockwise ? 1 : -1) * (r > 0 ? 1 : -1);
        ca = f[0] + da / 2 + side * h * db / chord;
        cb = f[1] + db / 2 - side * h * da / chord;
    } else {
        if (!line.has(offset_a) && !line.has(offset_b))
            throw fail(std::string("an arc needs ") + offset_a + " and " + offset_b + ", or R");
        ca = f[0] + line.value(offset_a).value_or(0) * m.unit_mm;
        cb = f[1] + line.value(offset_b).value_or(0) * m.unit_mm;
    }
    const double radius = std::hypot(f[0] - ca, f[1] - cb);
    const double end_radius = std::hypot(t[0] - ca, t[1] - cb);
    const double a0 = std::atan2(f[1] - cb, f[0] - ca);
    const double a1 = std::atan2(t[1] - cb, t[0] - ca);
    double sweep = a1 - a0;
    if (clockwise) {
        while (sweep >= -1e-12) sweep -= 2 * kPi;
    } else {
        while (sweep <= 1e-12) sweep += 2 * kPi;
    }
    if (std::hypot(t[0] - f[0], t[1] - f[1]) < 1e-9 && !line.has('R'))
        sweep = clockwise ? -2 * kPi : 2 * kPi;  // a whole circle
    const double by_tolerance = radius > settings.arc_tolerance_mm
                                    ? 2 * std::acos(1 - settings.arc_tolerance_mm / radius)
                                    : kPi;
    const double by_length = settings.max_segment_mm / std::max(radius, 1e-9);
    const int pieces = std::max(
        1, static_cast<int>(std::ceil(std::abs(sweep) / std::min(by_tolerance, by_length))));
    std::vector<PathPoint> path;
    for (int k = 1; k <= pieces; ++k) {
        if (k == pieces) {
            path.push_back({to, z_to});
            continue;
        }
        const double a = a0 + sweep * k / pieces;
        const double share = static_cast<double>(k) / pieces;
        // CAM rounds I J K: the end lies a micron or so off the start's circle. The radius moves
        // from the start's to the end's along the sweep, so the path meets the end without a step.
        const double r = radius + (end_radius - radius) * share;
        PathPoint p =
            from_abh({ca + r * std::cos(a), cb + r * std::sin(a), f[2] + (t[2] - f[2]) * share});
        if (m.plane == 17 && !(z_from && z_to)) p.z_mm = z_to;
        path.push_back(p);
    }
    return path;
}

// A job whose lines were numbered comes out numbered, from its first number on, by its own step,
// with a checksum where the line had one.
struct Numbering {
    std::optional<long> first, step, next;
    void saw(long number) {
        if (!first) {
            first = next = number;
        } else if (!step) {
            step = std::max(1L, number - *first);
            next = *first + *step;
        }
    }
    std::string line(const std::string& body, bool checksummed) {
        const long n = *next;
        next = n + step.value_or(1);
        if (checksummed) return gcode::numbered_line(n, body);
        std::string out = "N";  // appended piece by piece: see Code::text()
        out += std::to_string(n);
        out += ' ';
        out += body;
        return out;
    }
};

// The raw line without its line number and checksum, comments kept.
std::string body_of(std::string_view raw) {
    const std::string_view body = gcode::without_checksum(raw);
    std::size_t i = 0;
    while (i < body.size() && (body[i] == ' ' || body[i] == '\t')) ++i;
    std::string prefix;
    if (i < body.size() && body[i] == '/') prefix = "/", ++i;
    if (i < body.size() && (body[i] == 'N' || body[i] == 'n')) {
        ++i;
        while (i < body.size() && std::isdigit(static_cast<unsigned char>(body[i]))) ++i;
        while (i < body.size() && (body[i] == ' ' || body[i] == '\t')) ++i;
    }
    std::string out = prefix + std::string(body.substr(i));
    while (!out.empty() && (out.back() == '\r' || out.back() == ' ')) out.pop_back();
    return out;
}

// LinuxCNC's programming words and polar coordinates, which a plain G-code reader cannot
// evaluate: the reason, or empty.
std::string unplain_words(std::string_view raw) {
    const std::string words = gcode::strip_comments(gcode::without_checksum(raw));
    const auto first = words.find_first_not_of(" \t/");
    if (words.find_first_of("#[") != std::string::npos ||
        (first != std::string::npos && (words[first] == 'o' || words[first] == 'O')))
        return "parameters, expressions or O-word subroutines (LinuxCNC's '#', '[ ]', 'o'): calbox "
               "reads plain G-code; have the CAM post-processor write plain numbers";
    if (words.find_first_of("@^") != std::string::npos)
        return "polar coordinates ('@', '^'): have the CAM write X and Y";
    return {};
}

}  // namespace

std::string compensate_gcode(std::string_view job, const Correction& correct, const Covers& covers,
                             const CompensateSettings& settings, CompensateReport& report) {
    if (!(settings.max_segment_mm > 0) || !(settings.arc_tolerance_mm > 0))
        throw CompensateError("the segment length and arc tolerance must be positive");
    Writer writer(correct, covers, report);
    Modal m;
    Numbering numbering;
    std::string out;
    std::size_t start = 0;
    long number_of_line = 0;
    while (start <= job.size()) {
        const auto end = job.find('\n', start);
        const bool last = end == std::string_view::npos;
        std::string_view raw = job.substr(start, last ? std::string_view::npos : end - start);
        start = last ? job.size() + 1 : end + 1;
        if (last && raw.empty()) break;
        ++number_of_line;
        ++report.lines;
        const auto fail = [&](const std::string& why) -> CompensateError {
            return CompensateError("line " + std::to_string(number_of_line) + ": " + why);
        };
        if (raw.size() > kLongestLine)
            throw CompensateError("line " + std::to_string(number_of_line) + " is " +
                                  std::to_string(raw.size()) +
                                  " characters long: not G-code (a line holds at most " +
                                  std::to_string(kLongestLine) + ")");
        gcode::Line line;
        std::vector<Code> codes;
        try {
            if (const auto why = unplain_words(raw); !why.empty()) throw fail(why);
            line = gcode::parse_line(raw);
            codes = g_codes_of(line);
        } catch (const gcode::SyntaxError& e) {
            throw fail(e.what());
        }
        const bool numbered = line.line_number.has_value();
        const bool checksummed = gcode::without_checksum(raw).size() != raw.size();
        if (numbered) numbering.saw(*line.line_number);
        const auto emit = [&](const std::string& text) {
            out += numbered ? numbering.line(text, checksummed) : text;
            out += '\n';
        };
        const auto verbatim = [&] {
            if (numbered) {
                emit(body_of(raw));
            } else {
                out += raw;
                out += '\n';
            }
        };
        // G92, G28 / G30, G4, G53 and probing take axis words that are not a move.
        bool axis_words_not_a_move = false;
        std::vector<Code> kept_codes;  // the line's other G words, written ahead of its move
        for (const Code c : codes) {
            if (c.is_motion()) {
                m.motion = c.number;
                continue;
            }
            kept_codes.push_back(c);
            if (c.is(20)) {
                m.unit_mm = 25.4;
            } else if (c.is(21)) {
                m.unit_mm = 1;
            } else if (c.is(90)) {
                m.absolute = true;
            } else if (c.is(91)) {
                m.absolute = false;
            } else if (c.number == 90 && c.subcode == 1) {
                throw fail("absolute arc centres (G90.1): have the CAM write I J K relative");
            } else if (c.is(17) || c.is(18) || c.is(19)) {
                m.plane = c.number;
            } else if (c.is(80)) {
                m.motion = -1;
            } else if (c.number == 41 || c.number == 42) {
                throw fail("cutter radius compensation (" + c.text() +
                           "): the cutter's path is not in the file; have the CAM write the "
                           "compensated path");
            } else if (c.is(73) || c.is(76) || (c.number >= 81 && c.number <= 89)) {
                throw fail("canned cycle " + c.text() +
                           ": have the CAM post-processor expand cycles into moves");
            } else if (c.number >= 55 && c.number <= 59) {
                throw fail("work offset " + c.text() +
                           " is held by the controller, not the file: calbox compensates jobs in "
                           "G54, the frame it measured");
            } else if (c.is(10)) {
                throw fail("G10 sets offsets in the controller: not in a compensated job");
            } else if (c.is(53)) {
                if (line.has('X') || line.has('Y'))
                    throw fail(
                        "a move in machine coordinates (G53) with X or Y: their place "
                        "against the job's is not in the file");
                axis_words_not_a_move = true;
            } else if (c.is(92)) {
                axis_words_not_a_move = true;
                if (line.has('X') || line.has('Y')) {
                    if (!m.xy_known) throw fail("G92 with X or Y before the position is known");
                    if (auto x = line.value('X')) {
                        m.g92_offset_mm.x = m.xy_mm.x - *x * m.unit_mm;
                        m.written_xy.x = *x;
                    }
                    if (auto y = line.value('Y')) {
                        m.g92_offset_mm.y = m.xy_mm.y - *y * m.unit_mm;
                        m.written_xy.y = *y;
                    }
                }
                if (auto e = line.value('E')) m.e = *e;
                if (auto z = line.value('Z')) m.z_mm = *z * m.unit_mm, m.written_z = *z;
            } else if (c.number == 92 && (c.subcode == 1 || c.subcode == 2)) {
                axis_words_not_a_move = true;
                m.written_xy = {m.written_xy.x + m.g92_offset_mm.x / m.unit_mm,
                                m.written_xy.y + m.g92_offset_mm.y / m.unit_mm};
                m.g92_offset_mm = {};
            } else if (c.number == 92) {
                throw fail("G92.3 restores an offset the file did not set");
            } else if (c.is(28) || c.is(30)) {
                axis_words_not_a_move = true;
                m.xy_known = false, m.z_mm.reset(), m.written_z.reset();
            } else if (c.is(4)) {
                axis_words_not_a_move = true;
            } else if (c.number == 38) {
                if (line.has('X') || line.has('Y'))
                    throw fail("a probing move (" + c.text() +
                               ") with X or Y: where it stops is not known");
                axis_words_not_a_move = true;
            }
        }
        if (has_m(line, 82)) m.absolute_e = true;
        if (has_m(line, 83)) m.absolute_e = false;

        const bool axes = line.has('X') || line.has('Y') || line.has('Z');
        const bool arc_words = line.has('I') || line.has('J') || line.has('K') || line.has('R');
        const bool commanded_motion =
            std::any_of(codes.begin(), codes.end(), [](Code c) { return c.is_motion(); });
        const bool is_arc_mode = m.motion == 2 || m.motion == 3;
        const bool moves = !axis_words_not_a_move && m.motion >= 0 && line.command_letter != 'M' &&
                           line.command_letter != 'T' &&
                           (axes || (is_arc_mode && (arc_words || commanded_motion)));
        const bool moves_xy = moves && (is_arc_mode || line.has('X') || line.has('Y'));
        if (!moves_xy) {
            if (moves && line.has('Z')) {
                if (auto z = line.value('Z')) {
                    m.z_mm = m.absolute ? *z * m.unit_mm : m.z_mm.value_or(0) + *z * m.unit_mm;
                    m.written_z = m.absolute ? *z : m.written_z.value_or(0) + *z;
                }
            }
            if (moves && line.has('E')) {
                if (auto e = line.value('E')) m.e = m.absolute_e ? *e : m.e + *e;
            }
            verbatim();
            continue;
        }
        if (line.block_delete)
            throw fail("a move under block delete ('/'): whether it runs is the operator's switch");
        if (!m.xy_known && !(m.absolute && line.has('X') && line.has('Y')))
            throw fail(
                "a move that gives one axis where the other's position is unknown (after G28 or at "
                "the start)");
        // The move's end on the calibrated frame, in mm.
        const Point2 from = m.xy_mm;
        Point2 to = from;
        if (auto x = line.value('X'))
            to.x = m.absolute ? *x * m.unit_mm + m.g92_offset_mm.x : from.x + *x * m.unit_mm;
        if (auto y = line.value('Y'))
            to.y = m.absolute ? *y * m.unit_mm + m.g92_offset_mm.y : from.y + *y * m.unit_mm;
        const std::optional<double> z_from = m.z_mm;
        std::optional<double> z_to = m.z_mm;
        if (auto z = line.value('Z'))
            z_to = m.absolute ? *z * m.unit_mm : m.z_mm.value_or(0) + *z * m.unit_mm;
        const std::optional<double> e_word = line.value('E');
        const std::vector<PathPoint> path =
            is_arc_mode ? arc_path(line, m, from, to, z_from, z_to, settings, fail)
                        : line_path(m.xy_known, from, to, z_from, z_to, settings);
        if (is_arc_mode) ++report.arcs;
        ++report.moves;
        const bool moves_z = z_to.has_value() && (line.has('Z') || (is_arc_mode && m.plane != 17));
        const std::string command = m.motion == 0 ? "G0" : "G1";
        // A tenth of a micron either way: 4 decimals of a mm, 5 of an inch.
        const int decimals = m.unit_mm > 1 ? 5 : 4;
        const double e_from = m.e;
        const double e_total = e_word ? (m.absolute_e ? *e_word - m.e : *e_word) : 0;
        const std::size_t n = path.size();
        for (std::size_t k = 0; k < n; ++k) {
            const double share = static_cast<double>(k + 1) / static_cast<double>(n);
            const Point2 c = writer.corrected(path[k].xy);
            // Back to the job's frame and units.
            const Point2 job_xy{(c.x - m.g92_offset_mm.x) / m.unit_mm,
                                (c.y - m.g92_offset_mm.y) / m.unit_mm};
            std::string text;
            if (k == 0)
                for (const Code code : kept_codes) text += code.text() + " ";
            text += command;
            if (m.absolute) {
                text += " X" + number(job_xy.x, decimals) + " Y" + number(job_xy.y, decimals);
                m.written_xy = job_xy;
            } else {
                const double dx = std::stod(number(job_xy.x - m.written_xy.x, decimals));
                const double dy = std::stod(number(job_xy.y - m.written_xy.y, decimals));
                text += " X" + number(dx, decimals) + " Y" + number(dy, decimals);
                m.written_xy = {m.written_xy.x + dx, m.written_xy.y + dy};
            }
            if (moves_z && path[k].z_mm) {
                const double z_job = *path[k].z_mm / m.unit_mm;
                if (m.absolute || !m.written_z) {
                    text += " Z" + number(z_job, decimals);
                    m.written_z = z_job;
                } else {
                    const double dz = std::stod(number(z_job - *m.written_z, decimals));
                    text += " Z" + number(dz, decimals);
                    *m.written_z += dz;
                }
            }
            if (e_word) {
                text += " E" + number(m.absolute_e ? e_from + e_total * share
                                                   : e_total / static_cast<double>(n),
                                      5);
            }
            if (k == 0) {
                for (const auto& w : line.parameters) {
                    if (std::string_view("XYZEIJKRG").find(w.letter) != std::string_view::npos)
                        continue;
                    text += ' ';
                    text += w.letter;
                    if (w.value) text += number(*w.value, 6);
                }
            }
            if (k + 1 == n) {
                const std::string comment = comment_of(gcode::without_checksum(raw));
                if (!comment.empty()) text += " " + comment;
            }
            emit(text);
            ++report.pieces;
        }
        m.xy_mm = to;
        m.xy_known = true;
        m.z_mm = z_to;
        if (e_word) m.e = m.absolute_e ? *e_word : m.e + *e_word;
    }
    return out;
}

std::string compensate_scanner_csv(std::string_view job, const Correction& correct,
                                   const Covers& covers, const CompensateSettings& settings,
                                   CompensateReport& report) {
    if (!(settings.max_segment_mm > 0))
        throw CompensateError("the segment length must be positive");
    Writer writer(correct, covers, report);
    std::istringstream in{std::string(job)};
    std::string raw, out;
    long number_of_line = 0;
    std::optional<Point2> at;
    char line[128];
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
        double x = 0, y = 0, power = 0;
        char tail = 0;
        if (std::sscanf(raw.c_str(), "%lf,%lf,%lf%c", &x, &y, &power, &tail) != 3 ||
            !std::isfinite(x) || !std::isfinite(y) || !(power >= 0 && power <= 1))
            throw CompensateError("line " + std::to_string(number_of_line) +
                                  ": expected x_mm,y_mm,power with power from 0 to 1");
        const Point2 to{x, y};
        int pieces = 1;
        if (power > 0 && at) {
            pieces = std::max(1, static_cast<int>(std::ceil(std::hypot(to.x - at->x, to.y - at->y) /
                                                            settings.max_segment_mm)));
        }
        ++report.moves;
        for (int k = 1; k <= pieces; ++k) {
            const Point2 p = k == pieces ? to
                                         : Point2{at->x + (to.x - at->x) * k / pieces,
                                                  at->y + (to.y - at->y) * k / pieces};
            const Point2 c = writer.corrected(p);
            std::snprintf(line, sizeof line, "%.4f,%.4f,%s\n", c.x, c.y, number(power, 3).c_str());
            out += line;
            ++report.pieces;
        }
        at = to;
    }
    if (number_of_line == 0) throw CompensateError("the scanner job is empty");
    return out;
}

}  // namespace calbox::targets
