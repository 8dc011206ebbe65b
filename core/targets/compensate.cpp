#include "core/targets/compensate.hpp"

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

#include "core/number_text.hpp"
#include "core/targets/cutter_path.hpp"
#include "core/targets/gcode_line.hpp"
#include "core/targets/job_words.hpp"

namespace calbox::targets {
namespace {

using geometry::Point2;
using job_words::Code;
using job_words::command_words;
using job_words::CommandWords;
using job_words::g_codes_of;
using job_words::has_m;
using job_words::has_m_in;
using job_words::is_cycle;
using job_words::kOtherAxes;
using job_words::number;
using job_words::ReadLine;
using job_words::trailing_comment;

// No slicer or CAM program writes a line near this (PrusaSlicer's longest, its settings and
// thumbnail lines, stay under a few thousand characters); past it the file is not G-code.
constexpr std::size_t kLongestLine = 65536;

// What the controller holds between lines, as the job's lines set it. XY are kept in machine
// coordinates (the work system's zero and G92 applied), in mm; Z in the job's own frame, in mm
// (the correction does not move it; a move's pieces share it).
struct Modal {
    int motion = -1;  // 0..3, a canned cycle (73, 81..89), -1 before any and after G80
    bool absolute = true, absolute_e = true;
    double unit_mm = 1;  // 25.4 after G20
    int plane = 17;
    std::size_t work_system = 0;  // G54
    std::array<std::optional<Point2>, kWorkSystems> work_zero_mm;
    Point2 g92_offset_mm;
    // What G92.3 restores: the offset G92 last set (LinuxCNC's parameters 5211-5216), zero after
    // G92.1; unknown before the file sets one.
    std::optional<Point2> saved_g92_mm;
    Point2 xy_mm;
    bool xy_known = false;  // not until a move gives both axes (and not after G28)
    std::optional<double> z_mm;
    double e = 0;
    // The other axes' positions (rotary A B C, linear U V W), in the job's units, where known:
    // a move that drives one is shared along its pieces as Z is.
    std::map<char, double> other_axes;
    // The position last written, in the job's units and frame: relative moves are written as
    // differences of it, so that rounding never accumulates.
    Point2 written_xy;
    std::optional<double> written_z;
    // Canned cycles: G99 retracts to R, G98 to the height before the series of cycles (or R,
    // when that is lower); their R, Z, Q and P stay in force from block to block.
    bool retract_to_r = false;
    // G93: F is each move's inverse time (1 / minutes), so a move split in n pieces takes n F.
    bool inverse_time = false;
    std::optional<double> feed;  // the F in force (units per minute), where a line gave one
    std::optional<double> cycle_start_z_mm;
    std::optional<double> cycle_r, cycle_z, cycle_q, cycle_p;  // the job's units
    // Whether the file has the spindle turning (M3, M4; M5 and a tool change stop it), as
    // LinuxCNC's interpreter follows it from a stopped start: G86 and G88 need it turning.
    bool spindle_turning = false;
    // G95 (feed per revolution) and the S in force: LinuxCNC feeds by neither with S at 0.
    bool feed_per_rev = false;
    double spindle_speed = 0;

    // Machine = job * unit + offset, where the work system's zero is known.
    std::optional<Point2> offset_mm() const {
        const auto& zero = work_zero_mm[work_system];
        if (!zero) return std::nullopt;
        return Point2{zero->x + g92_offset_mm.x, zero->y + g92_offset_mm.y};
    }
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
                                const CompensateSettings& settings, double r_tolerance_mm,
                                const Fail& fail) {
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
        if (chord == 0)
            throw fail(
                "an R arc that ends where it starts: its centre is not defined (write it "
                "with I J K)");
        // Short by no more than the file's written precision, it is the half circle its rounding
        // hid, as LinuxCNC and Mach3 cut it.
        const double shortfall = chord / 2 - std::abs(r);
        if (!(shortfall <= r_tolerance_mm))
            throw fail("an R arc no controller could cut: radius " + number(std::abs(r), 5) +
                       " mm, chord " + number(chord, 5) + " mm, so R is " + number(shortfall, 5) +
                       " mm short of half the chord, past the file's written precision of " +
                       number(r_tolerance_mm, 6) + " mm; have the CAM write the arc again");
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
    // LinuxCNC's own bound on a centre-format arc whose end is off the start's circle: past
    // both, it refuses the arc, and so does calbox.
    const double radius_step = std::abs(end_radius - radius);
    if (job_words::arc_end_off_its_circle(radius, radius_step, m.unit_mm > 1))
        throw fail("an arc no controller could cut: its end is " + number(radius_step, 5) +
                   " mm off the circle through its start (radius " + number(radius, 5) +
                   " mm about its centre); have the CAM write the arc again");
    const double a0 = std::atan2(f[1] - cb, f[0] - ca);
    const double a1 = std::atan2(t[1] - cb, t[0] - ca);
    double sweep = a1 - a0;
    if (clockwise) {
        while (sweep >= -1e-12) sweep -= 2 * std::numbers::pi;
    } else {
        while (sweep <= 1e-12) sweep += 2 * std::numbers::pi;
    }
    if (std::hypot(t[0] - f[0], t[1] - f[1]) < 1e-9 && !line.has('R'))
        sweep = clockwise ? -2 * std::numbers::pi : 2 * std::numbers::pi;  // a whole circle
    // LinuxCNC's P: the arc goes round P times (P - 1 whole turns more).
    if (const auto turns = line.value('P')) {
        if (!(*turns >= 1 && *turns <= 1000 && *turns == std::floor(*turns)))
            throw fail("an arc's P (its turns) is a whole number from 1 to 1000, not " +
                       number(*turns, 4));
        sweep += (clockwise ? -2 * std::numbers::pi : 2 * std::numbers::pi) * (*turns - 1);
    }
    const double by_tolerance = radius > settings.arc_tolerance_mm
                                    ? 2 * std::acos(1 - settings.arc_tolerance_mm / radius)
                                    : std::numbers::pi;
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

// The drilling cycles that dwell at the hole's bottom, for their P.
bool dwells_at_bottom(int motion) {
    return motion == 82 || motion == 86 || motion == 88 || motion == 89;
}

// The polar words of a line (LinuxCNC's '@' distance and '^' angle in degrees), taken out of it.
struct Polar {
    std::optional<double> distance, angle_deg;
    bool any() const { return distance || angle_deg; }
};

Polar take_polar_words(std::string& raw) {
    Polar polar;
    bool in_paren = false;
    for (std::size_t i = 0; i < raw.size(); ++i) {
        const char c = raw[i];
        if (in_paren) {
            in_paren = c != ')';
            continue;
        }
        if (c == '(') {
            in_paren = true;
            continue;
        }
        if (c == ';' || c == '*') break;
        if (c != '@' && c != '^') continue;
        std::size_t j = i + 1;
        while (j < raw.size() && (raw[j] == ' ' || raw[j] == '\t')) ++j;
        std::size_t k = j;
        if (k < raw.size() && (raw[k] == '-' || raw[k] == '+')) ++k;
        while (k < raw.size() &&
               (std::isdigit(static_cast<unsigned char>(raw[k])) != 0 || raw[k] == '.'))
            ++k;
        double v = 0;
        const char* first = raw.data() + j + (j < raw.size() && raw[j] == '+' ? 1 : 0);
        const auto [end, ec] = std::from_chars(first, raw.data() + k, v);
        if (ec != std::errc() || end != raw.data() + k)
            throw gcode::SyntaxError(std::string("bad number after '") + c + "'");
        (c == '@' ? polar.distance : polar.angle_deg) = v;
        raw.erase(i, k - i);
        --i;
    }
    return polar;
}

// The most decimals written in the line's words `letters`: the file's written precision there.
int written_decimals(std::string_view raw, std::string_view letters) {
    const std::string body = gcode::strip_comments(gcode::without_checksum(raw));
    int most = 0;
    for (std::size_t i = 0; i < body.size(); ++i) {
        const char c = static_cast<char>(std::toupper(static_cast<unsigned char>(body[i])));
        if (letters.find(c) == std::string_view::npos) continue;
        std::size_t j = i + 1;
        while (j < body.size() && (body[j] == '-' || body[j] == '+' || body[j] == ' ')) ++j;
        while (j < body.size() && std::isdigit(static_cast<unsigned char>(body[j])) != 0) ++j;
        if (j < body.size() && body[j] == '.') {
            int d = 0;
            while (++j < body.size() && std::isdigit(static_cast<unsigned char>(body[j])) != 0) ++d;
            most = std::max(most, d);
        }
    }
    return most;
}

// A word that changes what a job's coordinates mean, or names a machine calbox does not
// compensate: why it is refused, or "".
bool is_lathe_word(const Code& c) {
    return c.is(7) || c.is(8) || c.is(76) || (c.number >= 70 && c.number <= 72 && c.subcode < 0);
}

bool is_cnc(Flavour f) {
    return f != Flavour::printer;
}

// The letters each CNC controller has: LinuxCNC's interpreter stops on any other ("Bad
// character"), grbl with its error 20. U V W on LinuxCNC: machines configured with them exist,
// though rs274's own default machine (XYZABC) refuses them. grbl's Q: the peck of the drilling
// cycles calbox writes out for it as moves; its D and H are read to be refused with the code
// they belong to (cutter compensation, tool length), which says more than the letter.
std::string_view letters_of(Flavour f) {
    return f == Flavour::linuxcnc ? "ABCDFGHIJKLMNPQRSTUVWXYZ" : "ABCDFGHIJKLMNPQRSTXYZ";
}

std::string controller_of(Flavour f) {
    return f == Flavour::linuxcnc ? "LinuxCNC" : f == Flavour::grbl ? "grbl" : "the printer";
}

// A G code's modal group, as RS274NGC numbers them (0 the non-modal codes), or -1 for a code
// outside the table.
int modal_group(const Code& c) {
    const int n = c.number;
    if (c.subcode >= 0) {
        if (n == 38 || (n == 33 && c.subcode == 1)) return 1;
        if (n == 59) return 12;
        if (n == 61) return 13;
        if (n == 92 || n == 28 || n == 30) return 0;
        if (n == 43) return 8;
        if (n == 90 || n == 91) return 4;
        if (n == 41 || n == 42) return 7;
        return -1;
    }
    if ((n >= 0 && n <= 3) || n == 33 || n == 73 || n == 76 || (n >= 80 && n <= 89)) return 1;
    if (n >= 17 && n <= 19) return 2;
    if (n == 90 || n == 91) return 3;
    if (n >= 93 && n <= 95) return 5;
    if (n == 20 || n == 21) return 6;
    if (n >= 40 && n <= 42) return 7;
    if (n == 43 || n == 49) return 8;
    if (n == 98 || n == 99) return 10;
    if (n >= 54 && n <= 59) return 12;
    if (n == 61 || n == 64) return 13;
    if (n == 4 || n == 10 || n == 28 || n == 30 || n == 52 || n == 53 || n == 92) return 0;
    return -1;
}

// LinuxCNC's G codes (its G-code reference; grbl's are a subset): any other stops its
// interpreter ("Unknown g code used"), so calbox never passes one on as written.
bool is_known_code(const Code& c) {
    const int n = c.number, s = c.subcode;
    if (s < 0)
        return (n >= 0 && n <= 5) || n == 7 || n == 8 || n == 10 || (n >= 17 && n <= 21) ||
               n == 28 || n == 30 || n == 33 || (n >= 40 && n <= 43) || n == 49 || n == 52 ||
               n == 53 || (n >= 54 && n <= 59) || n == 61 || n == 64 || (n >= 70 && n <= 74) ||
               n == 76 || (n >= 80 && n <= 99);
    switch (n) {
        case 5:
            return s >= 1 && s <= 3;
        case 17:
        case 18:
        case 19:
        case 28:
        case 30:
        case 33:
        case 61:
        case 90:
        case 91:
            return s == 1;
        case 38:
            return s >= 2 && s <= 5;
        case 41:
        case 42:
            return s == 1;
        case 43:
            return s == 1 || s == 2;
        case 59:
            return s >= 1 && s <= 3;
        case 71:
        case 72:
            return s == 1 || s == 2;
        case 92:
            return s >= 1 && s <= 3;
        default:
            return false;
    }
}

// The M codes each controller has: LinuxCNC's (its M-code reference, user codes M100-M199
// included) and grbl 1.1's (its gcode.c; any other is its error 20, a tool change M6 too).
bool is_known_m(Flavour f, double value) {
    const int m = static_cast<int>(value);
    if (f == Flavour::grbl) return (m >= 0 && m <= 5) || (m >= 7 && m <= 9) || m == 30 || m == 56;
    return (m >= 0 && m <= 9) || m == 19 || m == 30 || (m >= 48 && m <= 53) || m == 60 || m == 61 ||
           (m >= 62 && m <= 68) || (m >= 70 && m <= 73) || m == 98 || m == 99 ||
           (m >= 100 && m <= 199);
}

std::string refused_word(const Code& c, const gcode::Line& line, Flavour flavour) {
    if (is_lathe_word(c))
        return "a lathe job (" + c.text() +
               "): calbox compensates mills, routers, lasers and printers, not lathes";
    if (c.number == 41 || c.number == 42)
        return "cutter radius compensation (" + c.text() +
               "): the cutter's path is not in the file; have the CAM write the compensated path";
    if (c.number == 90 && c.subcode == 1)
        return "absolute arc centres (G90.1): have the CAM write I J K relative";
    if (c.is(52) && flavour != Flavour::linuxcnc)
        return "a local offset (G52): " + controller_of(flavour) +
               " has none; have the CAM write the job in one work system";
    if (c.is(68)) return "coordinate rotation (G68): have the CAM write the rotated job";
    if (c.is(51)) return "scaling (G51): have the CAM write the scaled job";
    if (c.number == 5 && (c.subcode < 0 || c.subcode <= 3))
        return "a spline (" + c.text() + "): have the CAM write arcs or lines";
    if (c.number == 43 && c.subcode >= 1 && (line.has('X') || line.has('Y')))
        return "a tool offset in X or Y (" + c.text() + "): the tool's place is not in the file";
    if (c.number == 33 && (line.has('X') || line.has('Y')))
        return "a spindle-synchronised move in X or Y (" + c.text() + "): threading on a lathe";
    return {};
}

// Where to command for the tool to land on machine point `p`: the correction inside the
// measured area, and its nearest edge point's correction beyond it (held, never extrapolated),
// each held point counted in `report`.
Point2 held_correction(const MachineCorrection& correction, Point2 p, CompensateReport& report) {
    if (report.keep_path) report.path_mm.push_back(p);
    const auto& area = correction.measured_mm;
    if (area.contains(p)) return correction.correct(p);
    const Point2 q = area.nearest(p);
    const Point2 c = correction.correct(q);
    ++report.held;
    report.held_farthest_mm = std::max(report.held_farthest_mm, std::hypot(p.x - q.x, p.y - q.y));
    return {p.x + c.x - q.x, p.y + c.y - q.y};
}

class Compensator {
  public:
    Compensator(const MachineCorrection& correction, const JobFrame& frame,
                const CompensateSettings& settings, CompensateReport& report)
        : correction_(correction), frame_(frame), settings_(settings), report_(report) {
        m_.work_zero_mm = frame.work_zero_mm;
        // grbl powers up in G0: axis words alone move. LinuxCNC and printers start with none.
        if (frame.flavour == Flavour::grbl) m_.motion = 0;
        if (frame.start_mm) {
            m_.xy_mm = *frame.start_mm;
            m_.xy_known = true;
            if (const auto offset = m_.offset_mm())
                m_.written_xy = job_of(*frame.start_mm, *offset);
        }
    }

    std::string run(std::string_view job) {
        std::vector<std::pair<std::string, long>> lines;
        if (gcode::uses_ngc_language(job)) {
            report_.ran_program = true;
            try {
                for (auto& l : gcode::run_ngc_program(job, settings_.program))
                    lines.emplace_back(std::move(l.text), l.source_line);
            } catch (const gcode::ProgramError& e) {
                throw CompensateError(e.what());
            }
        } else {
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
        }
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

  private:
    CompensateError fail(const std::string& why) const {
        return CompensateError("line " + std::to_string(line_number_) + ": " + why);
    }

    // A point in the job's frame and units as the machine's, and back.
    Point2 offset_or_fail(const char* doing) const {
        const auto offset = m_.offset_mm();
        if (!offset) {
            static const char* names[] = {"G54", "G55",   "G56",   "G57",  "G58",
                                          "G59", "G59.1", "G59.2", "G59.3"};
            const std::string name = names[m_.work_system];
            throw fail(std::string(doing) + " in " + name +
                       ", whose zero the controller holds and the file does not set: give it "
                       "(calbox compensate --work-zero " +
                       name + "=X,Y, machine coordinates) or set it in the job (G10 L2)");
        }
        return *offset;
    }
    Point2 machine_of(Point2 job, Point2 offset) const {
        return {job.x * m_.unit_mm + offset.x, job.y * m_.unit_mm + offset.y};
    }
    Point2 job_of(Point2 machine, Point2 offset) const {
        return {(machine.x - offset.x) / m_.unit_mm, (machine.y - offset.y) / m_.unit_mm};
    }

    // Whatever changes the job's frame (units, work system, offsets) keeps the written
    // position where it is on the machine.
    template <typename Change>
    void reframe(const Change& change) {
        const auto before = m_.offset_mm();
        const Point2 at = before ? machine_of(m_.written_xy, *before) : Point2{};
        change();
        if (const auto after = m_.offset_mm(); before && after) m_.written_xy = job_of(at, *after);
    }

    // Where the point the job means lies on the machine once the job is placed turned (itself
    // when it is not).
    Point2 placed(Point2 p) const {
        if (frame_.turn_rad == 0 && frame_.scale == 1) return p;
        const Point2 pivot = *frame_.work_zero_mm[0];
        const double c = frame_.scale * std::cos(frame_.turn_rad),
                     s = frame_.scale * std::sin(frame_.turn_rad);
        const Point2 d{p.x - pivot.x, p.y - pivot.y};
        return {pivot.x + c * d.x - s * d.y, pivot.y + s * d.x + c * d.y};
    }
    void refuse_when_turned(const std::string& what) const {
        if (frame_.turn_rad != 0 || frame_.scale != 1)
            throw fail(what +
                       " in a job placed turned with the stock (--work-zero camera, --register): "
                       "the turn is about G54's zero as the camera gives it; have the CAM write "
                       "the job in G54 alone, without offsets of its own");
    }

    void inside_travel(Point2 unplaced, Point2 offset) const {
        const Point2 p = placed(unplaced);
        if (frame_.travel_mm.contains(p)) return;
        const Point2 job = job_of(unplaced, offset);
        const auto& t = frame_.travel_mm;
        throw fail("the point X" + number(job.x, 4) + " Y" + number(job.y, 4) + " is at machine X" +
                   number(p.x, 3) + " Y" + number(p.y, 3) + " mm, beyond the machine's travel (X " +
                   number(t.min_x_mm, 3) + ".." + number(t.max_x_mm, 3) + ", Y " +
                   number(t.min_y_mm, 3) + ".." + number(t.max_y_mm, 3) +
                   " mm): check the job's work zero, or the travel in the machine file");
    }

    Point2 corrected(Point2 p) { return held_correction(correction_, placed(p), report_); }

    void emit(const std::string& text) {
        out_ += numbered_ ? numbering_.line(text, checksummed_) : text;
        out_ += '\n';
    }
    void verbatim(std::string_view raw) {
        if (numbered_) {
            emit(body_of(raw));
        } else {
            out_ += raw;
            out_ += '\n';
        }
    }

    // The end of an XY move on the machine: X Y words (or polar words) in the job's frame.
    Point2 end_of(const gcode::Line& line, const Polar& polar, Point2 offset) const {
        const Point2 from = m_.xy_mm;
        if (polar.any()) {
            const Point2 now = job_of(from, offset);
            const double r_now = std::hypot(now.x, now.y);
            const double a_now = std::atan2(now.y, now.x) * 180 / std::numbers::pi;
            const double r =
                m_.absolute ? polar.distance.value_or(r_now) : r_now + polar.distance.value_or(0);
            const double a = (m_.absolute ? polar.angle_deg.value_or(a_now)
                                          : a_now + polar.angle_deg.value_or(0)) *
                             std::numbers::pi / 180;
            return machine_of({r * std::cos(a), r * std::sin(a)}, offset);
        }
        Point2 to = from;
        if (auto x = line.value('X'))
            to.x = m_.absolute ? *x * m_.unit_mm + offset.x : from.x + *x * m_.unit_mm;
        if (auto y = line.value('Y'))
            to.y = m_.absolute ? *y * m_.unit_mm + offset.y : from.y + *y * m_.unit_mm;
        return to;
    }

    // X Y of a corrected machine point as the job writes them (absolute, or relative to what
    // was written last), the written position moved on.
    std::string xy_words(Point2 corrected_mm, Point2 offset, int decimals) {
        const Point2 job_xy = job_of(corrected_mm, offset);
        if (m_.absolute) {
            m_.written_xy = job_xy;
            return " X" + number(job_xy.x, decimals) + " Y" + number(job_xy.y, decimals);
        }
        const double dx = std::stod(number(job_xy.x - m_.written_xy.x, decimals));
        const double dy = std::stod(number(job_xy.y - m_.written_xy.y, decimals));
        m_.written_xy = {m_.written_xy.x + dx, m_.written_xy.y + dy};
        return " X" + number(dx, decimals) + " Y" + number(dy, decimals);
    }
    int decimals() const { return m_.unit_mm > 1 ? 5 : 4; }  // a tenth of a micron either way

    void work_offsets(const gcode::Line& line) {
        const auto l = line.value('L');
        const bool printer = frame_.flavour == Flavour::printer;
        if (!l) {
            if (printer) {
                // Marlin, RepRapFirmware and Klipper: firmware retraction. RepRapFirmware's
                // G10 P sets a tool's offsets or temperatures; offsets move the tool in XY.
                if (line.has('P') && (line.has('X') || line.has('Y')))
                    throw fail(
                        "G10 P with X or Y sets a tool's offset in the controller: the "
                        "tool's place is not in the file");
                return;
            }
            throw fail("G10 without L: set a work offset with G10 L2 or G10 L20");
        }
        if (*l == 1 || *l == 10 || *l == 11) return;  // the tool table: lengths, not XY
        if (*l != 2 && *l != 20)
            throw fail("G10 L" + number(*l, 3) + ": calbox tracks work offsets set by L2 and L20");
        if (line.value('R').value_or(0) != 0)
            throw fail("G10 with R rotates a work system: have the CAM write the rotated job");
        const double p = line.value('P').value_or(0);
        if (!(p >= 0 && p <= 9 && p == std::floor(p)))
            throw fail("G10 L" + number(*l, 0) + " P" + number(p, 3) +
                       ": P is 0 (the system in use) or 1 to 9 (G54 to G59.3)");
        const std::size_t system = p == 0 ? m_.work_system : static_cast<std::size_t>(p) - 1;
        const auto x = line.value('X'), y = line.value('Y');
        if (!x && !y) return;
        refuse_when_turned("G10 L" + number(*l, 0) + " with X or Y");
        reframe([&] {
            auto& zero = m_.work_zero_mm[system];
            if (*l == 2) {
                // Machine coordinates of the system's zero (G91 has no effect on L2).
                if ((!x || !y) && !zero)
                    throw fail("G10 L2 sets one axis of a work system whose zero is not known");
                Point2 z = zero.value_or(Point2{});
                if (x) z.x = *x * m_.unit_mm;
                if (y) z.y = *y * m_.unit_mm;
                zero = z;
            } else {
                // The zero that makes the current position read X Y in that system.
                if (!m_.xy_known)
                    throw fail(
                        "G10 L20 before the position is known (after G28 or at the "
                        "start)");
                if ((!x || !y) && !zero)
                    throw fail("G10 L20 sets one axis of a work system whose zero is not known");
                // The controller stands where it was sent, the corrected point: the line is
                // rewritten so that the zero it sets is the intended one.
                const Point2 sent = machine_of(m_.written_xy, offset_or_fail("G10 L20"));
                Point2 z = zero.value_or(Point2{});
                if (x) z.x = m_.xy_mm.x - m_.g92_offset_mm.x - *x * m_.unit_mm;
                if (y) z.y = m_.xy_mm.y - m_.g92_offset_mm.y - *y * m_.unit_mm;
                zero = z;
                rewritten_ = offset_line(line, {(sent.x - m_.g92_offset_mm.x - z.x) / m_.unit_mm,
                                                (sent.y - m_.g92_offset_mm.y - z.y) / m_.unit_mm});
            }
        });
    }

    // The G words of a line that set the controller's state (not motion); `not_a_move` when
    // the line's axis words are not a move.
    void state_words(const gcode::Line& line, const std::vector<Code>& codes, bool& not_a_move,
                     std::vector<Code>& kept_codes) {
        for (const Code c : codes) {
            if (const auto why = refused_word(c, line, frame_.flavour); !why.empty())
                throw fail(why);
            if (c.is_motion() || (c.subcode < 0 && is_cycle(c.number))) {
                if (is_cycle(c.number) && !is_cycle(m_.motion)) m_.cycle_start_z_mm = m_.z_mm;
                m_.motion = c.number;
                continue;
            }
            kept_codes.push_back(c);
            if (c.is(20) || c.is(21)) {
                reframe([&] { m_.unit_mm = c.is(20) ? 25.4 : 1; });
            } else if (c.is(90)) {
                m_.absolute = true;
            } else if (c.is(91)) {
                m_.absolute = false;
            } else if (c.is(17) || c.is(18) || c.is(19)) {
                m_.plane = c.number;
            } else if (c.is(80)) {
                m_.motion = -1;
            } else if (c.is(93) || c.is(94) || c.is(95)) {
                m_.inverse_time = c.is(93);
                m_.feed_per_rev = c.is(95);
            } else if (c.is(98) || c.is(99)) {
                m_.retract_to_r = c.is(99);
            } else if ((c.number >= 54 && c.number <= 58 && c.subcode < 0) ||
                       (c.number == 59 && c.subcode <= 3)) {
                const std::size_t system = c.number == 59 && c.subcode > 0
                                               ? static_cast<std::size_t>(5 + c.subcode)
                                               : static_cast<std::size_t>(c.number - 54);
                if (system != 0) refuse_when_turned(c.text());
                reframe([&] { m_.work_system = system; });
            } else if (c.is(10)) {
                not_a_move = true;
                work_offsets(line);
            } else if (c.is(11)) {
                not_a_move = true;
            } else if (c.is(53)) {
                // Machine coordinates for this line: the controller's own places (parking,
                // tool change), passed as written.
                machine_move_ = line.has('X') || line.has('Y');
            } else if (c.is(92)) {
                not_a_move = true;
                if (line.has('X') || line.has('Y')) {
                    refuse_when_turned("G92 with X or Y");
                    if (!m_.xy_known)
                        throw fail(
                            "G92 with X or Y before the position is known: it says the tool is "
                            "there, wherever it stands; give where it stands when the job starts "
                            "(calbox compensate --start-at X,Y, machine coordinates)");
                    offset_or_fail("G92");
                    const Point2 zero = *m_.work_zero_mm[m_.work_system];
                    reframe([&] {
                        if (auto x = line.value('X'))
                            m_.g92_offset_mm.x = m_.xy_mm.x - zero.x - *x * m_.unit_mm;
                        if (auto y = line.value('Y'))
                            m_.g92_offset_mm.y = m_.xy_mm.y - zero.y - *y * m_.unit_mm;
                    });
                    m_.saved_g92_mm = m_.g92_offset_mm;
                    // The controller stands at the corrected point: said to read there what the
                    // written position reads in the intended frame, its offset is the intended one.
                    rewritten_ = offset_line(line, m_.written_xy);
                }
                if (auto e = line.value('E')) m_.e = *e;
                if (auto z = line.value('Z')) m_.z_mm = *z * m_.unit_mm, m_.written_z = *z;
                for (const char a : kOtherAxes)
                    if (auto v = line.value(a)) m_.other_axes[a] = *v;
            } else if (c.number == 92 && (c.subcode == 1 || c.subcode == 2 || c.subcode == 3)) {
                // No axis words of its own: a move on its line runs in the frame it leaves.
                if (frame_.flavour == Flavour::grbl && c.subcode != 1)
                    throw fail(c.text() + ": grbl has G92.1 only (its error 20)");
                if (c.subcode == 3 && !m_.saved_g92_mm)
                    throw fail(
                        "G92.3 restores an offset the file did not set (the controller's "
                        "parameters hold it)");
                const Point2 to = c.subcode == 3 ? *m_.saved_g92_mm : Point2{};
                reframe([&] { m_.g92_offset_mm = to; });
                if (c.subcode == 1) m_.saved_g92_mm = Point2{};
            } else if (c.number == 92) {
                throw fail(c.text() + " is no offset code");
            } else if (c.is(52)) {
                // LinuxCNC's local offset: the G92 offset set to the words given, not from where
                // the tool is, so the controller's frame and the intended one stay the same.
                not_a_move = true;
                reframe([&] {
                    if (auto x = line.value('X')) m_.g92_offset_mm.x = *x * m_.unit_mm;
                    if (auto y = line.value('Y')) m_.g92_offset_mm.y = *y * m_.unit_mm;
                });
            } else if (c.is(28) || c.is(30)) {
                not_a_move = true;
                m_.xy_known = false, m_.z_mm.reset(), m_.written_z.reset();
                m_.other_axes.clear();
            } else if (c.is(4)) {
                // LinuxCNC and grbl dwell, then move the line's axis words under the motion in
                // force; a printer's G4 is the line's one command.
                not_a_move = not_a_move || !is_cnc(frame_.flavour) ||
                             !(line.has('X') || line.has('Y') || line.has('Z'));
            } else if (c.number == 38) {
                if (line.has('X') || line.has('Y'))
                    throw fail("a probing move (" + c.text() +
                               ") with X or Y: where it stops is not known");
                not_a_move = true;
            }
        }
    }

    // The line's words as its controller reads them: on LinuxCNC and grbl blanks count for
    // nothing and only the controller's letters are words; LinuxCNC's and printers' polar words
    // ('@', '^') taken out first.
    // LinuxCNC stops on a '(' inside a '(' comment ("Nested comment found"); grbl reads the
    // comment to its first ')'. A ';' comment holds anything.
    static void refuse_nested_comment(std::string_view raw) {
        for (std::size_t i = 0; i < raw.size() && raw[i] != ';'; ++i) {
            if (raw[i] != '(') continue;
            const std::size_t close = raw.find(')', i);
            const std::size_t inner = raw.find('(', i + 1);
            if (inner < close)
                throw gcode::SyntaxError("column " + std::to_string(inner + 1) +
                                         ": a '(' inside a comment (a nested comment)");
            if (close == std::string_view::npos) return;  // named where the words are read
            i = close;
        }
    }

    std::string words_of(const std::string& raw, Polar* polar = nullptr,
                         std::string_view more_letters = {}) const {
        std::string text = raw;
        if (frame_.flavour != Flavour::grbl) {
            const Polar p = take_polar_words(text);
            if (polar) *polar = p;
        }
        if (!is_cnc(frame_.flavour)) return text;
        if (frame_.flavour == Flavour::linuxcnc) refuse_nested_comment(text);
        std::string words =
            more_letters.empty()
                ? gcode::cnc_words(text, letters_of(frame_.flavour))
                : gcode::cnc_words(text, std::string(letters_of(frame_.flavour)) += more_letters);
        // LinuxCNC reads N only as a line's first word (after a '/'); grbl takes it anywhere.
        if (frame_.flavour == Flavour::linuxcnc) {
            if (const auto at = words.find(" N"); at != std::string::npos)
                throw gcode::SyntaxError(
                    "'" + words.substr(at + 1, words.find(' ', at + 1) - at - 1) +
                    "': a line number after other words (N comes first on its line)");
        }
        return words;
    }

    // What LinuxCNC's interpreter and grbl refuse in a line whose words are all theirs: a letter
    // twice, two codes of one modal group, axis words with no motion to take them, and words
    // that no code on the line (or the motion in force) uses. `m_` holds the line's motion and
    // the F in force.
    // The rules a line's words keep whatever the controller holds: codes it has, one word per
    // letter, one code per modal group.
    void word_rules(const gcode::Line& line, const std::vector<Code>& codes) const {
        const auto who = [this] { return controller_of(frame_.flavour); };
        const auto stops = [&who] { return ": " + who() + " stops on it"; };
        for (const Code c : codes)
            if (!is_known_code(c))
                throw fail(c.text() + ": no such G code (" + who() +
                           " stops on it: \"Unknown g code used\")");
        const auto check_m = [&](double value) {
            if (value != std::floor(value))
                throw fail("M" + number(value, 4) + ": an M code is a whole number (" + who() +
                           " stops on it" +
                           (frame_.flavour == Flavour::grbl
                                ? ": its error 20)"
                                : ": \"Non integer value for integer\")"));
            if (!is_known_m(frame_.flavour, value))
                throw fail("M" + number(value, 0) + ": no such M code on " + who() +
                           " (it stops on it" +
                           (frame_.flavour == Flavour::grbl ? ": its error 20)"
                                                            : ": \"Unknown m code used\")"));
        };
        if (line.command_letter == 'M') check_m(line.command_number);
        for (const auto& w : line.parameters)
            if (w.letter == 'M' && w.value) check_m(*w.value);
        std::array<int, 256> seen{};
        if (line.command_letter == 'T') ++seen['T'];
        for (const auto& w : line.parameters)
            if (w.letter != 'G' && w.letter != 'M' &&
                ++seen[static_cast<unsigned char>(w.letter)] == 2)
                throw fail(std::string("two ") + w.letter + " words on one line" + stops());
        for (std::size_t i = 0; i < codes.size(); ++i)
            for (std::size_t j = i + 1; j < codes.size(); ++j)
                if (modal_group(codes[i]) >= 0 && modal_group(codes[i]) == modal_group(codes[j]))
                    throw fail("two G codes of one modal group on one line (" + codes[i].text() +
                               " and " + codes[j].text() + ")" + stops());
    }

    void cnc_rules(const gcode::Line& line, const std::vector<Code>& codes, bool polar) const {
        // Named only in a refusal: a line read builds no message.
        const auto who = [this] { return controller_of(frame_.flavour); };
        const auto stops = [&who] { return ": " + who() + " stops on it"; };
        word_rules(line, codes);
        negative_words(line);
        const auto on_line = [&](int number) {
            return std::any_of(codes.begin(), codes.end(),
                               [number](Code c) { return c.number == number; });
        };
        const bool motion_code =
            std::any_of(codes.begin(), codes.end(), [](Code c) { return modal_group(c) == 1; });
        // The non-modal codes that take the line's axis words for themselves.
        const bool sets_offset =
            on_line(52) || std::any_of(codes.begin(), codes.end(), [](Code c) { return c.is(92); });
        const bool axis_code = on_line(10) || on_line(28) || on_line(30) || sets_offset;
        bool axes = polar;
        for (const char a : std::string_view("XYZABCUVW")) axes = axes || line.has(a);
        if (axis_code && motion_code && axes)
            throw fail("two G codes on one line that both take the axis words" + stops());
        const int motion = motion_code || (axes && !axis_code) ? m_.motion : -1;
        if (axes && !axis_code && motion < 0)
            throw fail(
                "axis words with no motion in force (before any G0 G1 G2 G3, or after "
                "G80)" +
                stops());
        const bool arc = motion == 2 || motion == 3, cycle = is_cycle(motion);
        // A feed move needs a feed rate: LinuxCNC "Cannot do G1 with zero feed rate", grbl's
        // error 22; under G93 (inverse time) on the move's own line.
        // (LinuxCNC asks it of a G1 code even on a line without axis words.)
        const bool feeds =
            (motion == 1 || arc || cycle) &&
            (axes || motion_code || (arc && (line.has('I') || line.has('J') || line.has('K'))));
        if (feeds && m_.inverse_time && !(line.value('F').value_or(0) > 0))
            throw fail("a feed move under G93 (inverse time) without its F on the line" + stops());
        if (feeds && !m_.inverse_time && !(m_.feed.value_or(0) > 0))
            throw fail("a feed move with no feed rate in force (no F above 0 given yet)" + stops());
        const bool g10 = on_line(10);
        const auto unused = [&](char letter, std::string_view users) {
            if (line.has(letter))
                throw fail(std::string(1, letter) + " word with no " + std::string(users) +
                           " to use it" + stops());
        };
        if (!arc && motion != 87 && !g10) {
            unused('I', "G2 or G3");
            unused('J', "G2 or G3");
            unused('K', "G2 or G3");
        }
        if (arc) {
            const char other = m_.plane == 17 ? 'K' : m_.plane == 18 ? 'J' : 'I';
            if (line.has(other))
                throw fail(std::string(1, other) + " word in an arc in the " +
                           (m_.plane == 17   ? "XY"
                            : m_.plane == 18 ? "XZ"
                                             : "YZ") +
                           " plane" + stops());
        }
        if (!arc && !cycle && !g10) unused('R', "G2, G3, a drilling cycle or G10");
        if (!cycle && !g10) unused('L', "G10 or drilling cycle");
        const bool m_with_p = has_m_in(line, 50, 53) || has_m_in(line, 62, 66) || has_m(line, 98) ||
                              has_m_in(line, 100, 199);
        const bool arc_turns = arc && frame_.flavour == Flavour::linuxcnc;
        if (!on_line(4) && !g10 && !arc_turns && !on_line(64) && !m_with_p &&
            !dwells_at_bottom(motion))
            unused('P', "G4, G10, G64, an arc's turns, G82/G86/G88/G89 or M code");
        if (!(motion == 73 || motion == 83) && !on_line(64) && !g10 && !has_m_in(line, 66, 68) &&
            !has_m_in(line, 100, 199))
            unused('Q', "G73, G83, G64, G10 or M66-M68");
        if (!on_line(43)) unused('H', "G43");
        unused('D', "G41 or G42");
        // The words a code cannot go without (LinuxCNC's interpreter; grbl's errors 26 and 28).
        const auto positive = [&](char letter) { return line.value(letter).value_or(0) > 0; };
        if (on_line(4) && !(line.value('P').value_or(-1) >= 0))
            throw fail("G4 without its dwell time (a P of 0 or more)" + stops());
        if (sets_offset && !axes) throw fail("G52 or G92 with no axis word to set" + stops());
        if (on_line(96) && !line.has('S'))
            throw fail("G96 without its S (the surface speed)" + stops());
        if (arc && line.has('R') && (line.has('I') || line.has('J') || line.has('K')))
            throw fail("an arc given both by its radius (R) and its centre (I, J, K)" + stops());
        if ((on_line(73) || on_line(83) || ((motion == 73 || motion == 83) && line.has('Q'))) &&
            !positive('Q'))
            throw fail("G" + std::to_string(motion == 73 || on_line(73) ? 73 : 83) +
                       " without its peck depth (a Q above 0)" + stops());
        if (dwells_at_bottom(motion) && line.has('P') && !(line.value('P').value_or(-1) >= 0))
            throw fail("G" + std::to_string(motion) + " with a negative dwell (P)" + stops());
    }

    // Words whose value cannot be below 0: LinuxCNC's "Negative f word used", "Negative spindle
    // speed used", "Negative l word used", an H or D naming no tool; grbl's error 4 ("Negative
    // value received for an expected positive value") for F, P and S.
    void negative_words(const gcode::Line& line) const {
        const bool grbl = frame_.flavour == Flavour::grbl;
        const std::string_view letters = grbl ? "FPS" : "FSLHD";
        for (const auto& w : line.parameters) {
            if (!w.value || !(*w.value < 0) || letters.find(w.letter) == std::string_view::npos)
                continue;
            const std::string what = w.letter == 'F'   ? "feed rate"
                                     : w.letter == 'S' ? "spindle speed"
                                     : w.letter == 'P' ? "P word"
                                     : w.letter == 'L' ? "repeat count (L)"
                                                       : "tool number";
            throw fail("'" + std::string(1, w.letter) + number(*w.value, 4) + "': a negative " +
                       what + ": " + controller_of(frame_.flavour) + " stops on it" +
                       (grbl ? " (its error 4)" : ""));
        }
    }

    void line(const std::string& raw) {
        gcode::Line line;
        std::vector<Code> codes;
        Polar polar;
        try {
            line = gcode::parse_line(words_of(raw, &polar));
            codes = g_codes_of(line);
        } catch (const gcode::SyntaxError& e) {
            throw fail(std::string(e.what()) +
                       (is_cnc(frame_.flavour)
                            ? ": " + controller_of(frame_.flavour) + " stops on it too"
                            : std::string()));
        }
        numbered_ = line.line_number.has_value();
        checksummed_ = gcode::without_checksum(raw).size() != raw.size();
        if (numbered_) numbering_.saw(*line.line_number);
        bool not_a_move = false;
        machine_move_ = false;
        motion_before_ = m_.motion;
        std::vector<Code> kept_codes;  // the line's other G words, written ahead of its move
        rewritten_.reset();
        state_words(line, codes, not_a_move, kept_codes);
        // The F in force, as the controller keeps it (G93's F is each move's own).
        if (auto f = line.value('F'); f && !m_.inverse_time) m_.feed = *f;
        if (is_cnc(frame_.flavour)) cnc_rules(line, codes, polar.any());
        if (has_m(line, 98) || has_m(line, 99))
            throw fail(
                "a subprogram call or return (M98, M99): have the CAM write the program "
                "flat");
        if (has_m(line, 6)) m_.spindle_turning = false;
        if (has_m(line, 3) || has_m(line, 4)) m_.spindle_turning = true;
        if (const auto s = line.value('S')) m_.spindle_speed = *s;
        if (has_m(line, 5)) m_.spindle_turning = false;
        if (has_m(line, 82)) m_.absolute_e = true;
        if (has_m(line, 83)) m_.absolute_e = false;

        const bool axes = line.has('X') || line.has('Y') || line.has('Z') || polar.any();
        const bool commanded_motion = std::any_of(codes.begin(), codes.end(), [](Code c) {
            return c.is_motion() || (c.subcode < 0 && is_cycle(c.number));
        });
        // A printer's M or T command is the line's one command; on LinuxCNC and grbl M, S, F and
        // T words ride on a move like any other word.
        const bool not_a_command =
            !is_cnc(frame_.flavour) && (line.command_letter == 'M' || line.command_letter == 'T');
        if (machine_move_) return machine_move(raw, line);
        const bool cycles = !not_a_move && !not_a_command && is_cycle(m_.motion) &&
                            (axes || line.has('R') || commanded_motion);
        const bool arc_words = line.has('I') || line.has('J') || line.has('K') || line.has('R');
        const bool is_arc_mode = m_.motion == 2 || m_.motion == 3;
        const bool moves = !not_a_move && m_.motion >= 0 && m_.motion <= 3 && !not_a_command &&
                           (axes || (is_arc_mode && (arc_words || commanded_motion)));
        if (m_.feed_per_rev && m_.spindle_speed == 0 && (cycles || (moves && m_.motion != 0)))
            throw fail(
                "a feed per revolution (G95) with the spindle speed 0 (no S above 0): LinuxCNC "
                "stops on it (\"Cannot feed with zero spindle speed in feed per rev mode\")");
        if (cycles) return cycle(raw, line, polar, kept_codes);
        const bool moves_xy =
            moves && (is_arc_mode || line.has('X') || line.has('Y') || polar.any());
        if (!moves_xy) {
            if (polar.any()) throw fail("polar words ('@', '^') where no move takes them");
            if (moves && line.has('Z')) {
                if (auto z = line.value('Z')) {
                    m_.z_mm = m_.absolute ? *z * m_.unit_mm : m_.z_mm.value_or(0) + *z * m_.unit_mm;
                    m_.written_z = m_.absolute ? *z : m_.written_z.value_or(0) + *z;
                }
            }
            if (moves && line.has('E')) {
                if (auto e = line.value('E')) m_.e = m_.absolute_e ? *e : m_.e + *e;
            }
            if (!not_a_move && !not_a_command && m_.motion >= 0 && m_.motion <= 3)
                for (const char a : kOtherAxes)
                    if (auto v = line.value(a)) {
                        const auto now = m_.other_axes.find(a);
                        if (m_.absolute)
                            m_.other_axes[a] = *v;
                        else if (now != m_.other_axes.end())
                            now->second += *v;
                    }
            if (rewritten_)
                emit(*rewritten_ + trailing_comment(raw));
            else
                verbatim(raw);
            return;
        }
        move(raw, line, polar, kept_codes, is_arc_mode);
    }

    void machine_move(const std::string& raw, const gcode::Line& line) {
        if (!m_.absolute) throw fail("G53 in incremental mode (G91): LinuxCNC refuses it too");
        Point2 to = m_.xy_mm;
        if (!m_.xy_known && !(line.has('X') && line.has('Y'))) {
            verbatim(raw);  // one axis of a place the file does not give: still unknown
            m_.xy_known = false;
            return;
        }
        if (auto x = line.value('X')) to.x = *x * m_.unit_mm;
        if (auto y = line.value('Y')) to.y = *y * m_.unit_mm;
        if (!frame_.travel_mm.contains(to))
            throw fail("the machine-coordinate move (G53) to X" + number(to.x, 3) + " Y" +
                       number(to.y, 3) + " mm is beyond the machine's travel");
        if (line.has('Z')) {
            // G53's Z is the machine's, not the job's: the job's height is not known after it.
            m_.z_mm.reset();
            m_.written_z.reset();
        }
        reframe([&] {
            m_.xy_mm = to;
            m_.xy_known = true;
        });
        if (const auto offset = m_.offset_mm()) m_.written_xy = job_of(to, *offset);
        verbatim(raw);
    }

    void move(const std::string& raw, const gcode::Line& line, const Polar& polar,
              const std::vector<Code>& kept_codes, bool is_arc_mode) {
        if (line.block_delete)
            throw fail("a move under block delete ('/'): whether it runs is the operator's switch");
        if (!m_.xy_known && !(m_.absolute && line.has('X') && line.has('Y') && !polar.any()))
            throw fail(
                "a move that gives one axis where the other's position is unknown (after G28 or at "
                "the start)");
        const Point2 offset = offset_or_fail("a move");
        const Point2 from = m_.xy_mm;
        const Point2 to = end_of(line, polar, offset);
        const std::optional<double> z_from = m_.z_mm;
        std::optional<double> z_to = m_.z_mm;
        if (auto z = line.value('Z'))
            z_to = m_.absolute ? *z * m_.unit_mm : m_.z_mm.value_or(0) + *z * m_.unit_mm;
        const std::optional<double> e_word = line.value('E');
        const double r_tolerance_mm = written_precision_ * m_.unit_mm;
        // A helix shares its descent along its chords; from a height the file has not given,
        // each chord would take the whole of it at once (a straight move is written whole for
        // that; an arc cannot be).
        if (is_arc_mode && m_.plane == 17 && line.has('Z') && !z_from)
            throw fail(
                "an arc that changes height (a helix) from a height the file has not given: its "
                "chords cannot share the descent; give a Z move before it");
        // In the XZ or YZ plane the height is one of the arc's own coordinates: from a height the
        // file has not given, its centre and its path are not known (rs274 takes Z0 there; a
        // machine starts where its tool is).
        if (is_arc_mode && m_.plane != 17 && !z_from)
            throw fail(std::string("an arc in the ") + (m_.plane == 18 ? "XZ" : "YZ") +
                       " plane from a height the file has not given: its centre and path are "
                       "not known; give a Z move before it");
        const auto failing = [this](const std::string& why) { return fail(why); };
        const std::vector<PathPoint> path =
            is_arc_mode
                ? arc_path(line, m_, from, to, z_from, z_to, settings_, r_tolerance_mm, failing)
                // From a height the file has not given, a climb cannot be shared along pieces
                // (each would take the whole of it at once): the move is written whole, to its
                // corrected end, as one from a place not given is.
                : line_path(m_.xy_known && !(line.has('Z') && !z_from), from, to, z_from, z_to,
                            settings_);
        // The move's end as the job writes it; then, for an arc, every chord's end (an arc
        // bulges past the rectangle its ends lie in).
        inside_travel(to, offset);
        for (const auto& p : path) inside_travel(p.xy, offset);
        if (is_arc_mode) ++report_.arcs;
        ++report_.moves;
        const bool moves_z = z_to.has_value() && (line.has('Z') || (is_arc_mode && m_.plane != 17));
        const std::string command = m_.motion == 0 ? "G0" : "G1";
        const double e_from = m_.e;
        const double e_total = e_word ? (m_.absolute_e ? *e_word - m_.e : *e_word) : 0;
        const std::size_t n = path.size();
        // The other axes this move drives, from where they are to where it sends them.
        struct OtherAxis {
            char letter;
            double from, to;
        };
        std::vector<OtherAxis> others;
        for (const char a : kOtherAxes) {
            const auto v = line.value(a);
            if (!v) continue;
            const auto now = m_.other_axes.find(a);
            if (now == m_.other_axes.end()) {
                if (n > 1)
                    throw fail(std::string("a move that drives ") + a +
                               " from where the file has not said: it cannot be shared along "
                               "the move's pieces (give " +
                               a + " on an earlier move, or G92 " + a + ")");
                if (m_.absolute) m_.other_axes[a] = *v;
                continue;
            }
            others.push_back({a, now->second, m_.absolute ? *v : now->second + *v});
        }
        const CommandWords commands = command_words(line);
        for (std::size_t k = 0; k < n; ++k) {
            const double share = static_cast<double>(k + 1) / static_cast<double>(n);
            const Point2 c = corrected(path[k].xy);
            std::string text;
            if (k == 0)
                for (const Code code : kept_codes) text += code.text() + " ";
            text += command;
            text += xy_words(c, offset, decimals());
            if (moves_z && path[k].z_mm) text += z_word(*path[k].z_mm);
            if (e_word) {
                text += " E" + number(m_.absolute_e ? e_from + e_total * share
                                                    : e_total / static_cast<double>(n),
                                      5);
            }
            for (const auto& a : others) {
                text += ' ';
                text += a.letter;
                text += number(m_.absolute ? a.from + (a.to - a.from) * share
                                           : (a.to - a.from) / static_cast<double>(n),
                               6);
            }
            const auto feed = line.value('F');
            const bool per_piece_feed = m_.inverse_time && feed && m_.motion != 0;
            std::string left_out = per_piece_feed ? "XYZEIJKRGFM" : "XYZEIJKRGM";
            for (const auto& a : others) left_out += a.letter;
            if (is_arc_mode) left_out += 'P';  // the turns, traced
            if (k == 0) text += other_words(line, left_out) + commands.before;
            if (per_piece_feed) text += " F" + number(*feed * static_cast<double>(n), 6);
            if (k + 1 == n) text += commands.after;
            if (k + 1 == n) text += trailing_comment(raw);
            emit(text);
            ++report_.pieces;
        }
        m_.xy_mm = to;
        m_.xy_known = true;
        m_.z_mm = z_to;
        if (e_word) m_.e = m_.absolute_e ? *e_word : m_.e + *e_word;
        for (const auto& a : others) m_.other_axes[a.letter] = a.to;
    }

    std::string z_word(double z_mm) {
        const double z_job = z_mm / m_.unit_mm;
        if (m_.absolute || !m_.written_z) {
            m_.written_z = z_job;
            return " Z" + number(z_job, decimals());
        }
        const double dz = std::stod(number(z_job - *m_.written_z, decimals()));
        *m_.written_z += dz;
        return " Z" + number(dz, decimals());
    }

    // An offset line (G92, G10 L20) with its X and Y words given new values, everything else on
    // it as written.
    std::string offset_line(const gcode::Line& line, Point2 xy) const {
        std::string text;
        for (const Code c : g_codes_of(line)) {
            if (!text.empty()) text += ' ';
            text += c.text();
        }
        for (const auto& w : line.parameters) {
            if (w.letter == 'G' || w.letter == 'M') continue;
            text += ' ';
            text += w.letter;
            if (w.letter == 'X' || w.letter == 'Y')
                text += number(w.letter == 'X' ? xy.x : xy.y, decimals());
            else if (w.value)
                text += number(*w.value, 6);
        }
        const CommandWords m = command_words(line);
        text += m.before + m.after;
        return text;
    }

    static std::string other_words(const gcode::Line& line, std::string_view left_out) {
        std::string text;
        for (const auto& w : line.parameters) {
            if (left_out.find(w.letter) != std::string_view::npos) continue;
            text += ' ';
            text += w.letter;
            if (w.value) text += number(*w.value, 6);
        }
        return text;
    }

    // A canned cycle's block: each hole (L repeats of it) placed through the correction; the
    // cycle kept for LinuxCNC, written out as moves for controllers without cycles.
    void cycle(const std::string& raw, const gcode::Line& line, const Polar& polar,
               const std::vector<Code>& kept_codes) {
        if (line.block_delete)
            throw fail(
                "a drilling cycle under block delete ('/'): whether it runs is the "
                "operator's switch");
        if (m_.plane != 17)
            throw fail("a drilling cycle in the XZ or YZ plane (G18, G19): holes along X or Y");
        // R, Z, Q and P stay in force only while the same cycle does: a cycle entered anew (after
        // G80, another motion or another cycle) gives its own, as LinuxCNC asks ("R clearance
        // plane unspecified in cycle").
        if (motion_before_ != m_.motion)
            m_.cycle_r.reset(), m_.cycle_z.reset(), m_.cycle_q.reset(), m_.cycle_p.reset();
        if (auto r = line.value('R')) m_.cycle_r = *r;
        if (auto z = line.value('Z')) m_.cycle_z = *z;
        if (auto q = line.value('Q')) m_.cycle_q = *q;
        if (auto p = line.value('P')) m_.cycle_p = *p;
        const Code code{m_.motion, -1};
        if (!m_.cycle_r || !m_.cycle_z)
            throw fail("canned cycle " + code.text() +
                       " without its R or Z (retract plane and bottom of the hole): a cycle "
                       "entered anew gives its own, LinuxCNC keeps them only while the same "
                       "cycle goes on");
        if (dwells_at_bottom(m_.motion) && !m_.cycle_p)
            throw fail("canned cycle " + code.text() +
                       " without its dwell (P): LinuxCNC stops on it (\"Dwell time p word "
                       "missing\")");
        if ((m_.motion == 86 || m_.motion == 88) && !m_.spindle_turning)
            throw fail(
                "canned cycle " + code.text() +
                " with the spindle not turning (no M3 or M4 since the start, an M5 or a tool "
                "change): "
                "LinuxCNC stops on it (\"Spindle not turning\")");
        // A retract plane below the hole's bottom drills upwards: LinuxCNC stops on it. Under
        // G91 Z is taken from R, so a Z above 0 is the same.
        if (m_.absolute ? *m_.cycle_r < *m_.cycle_z : *m_.cycle_z > 0)
            throw fail("canned cycle " + code.text() + " with its retract plane R" +
                       number(*m_.cycle_r, 4) + " below the hole's bottom Z" +
                       number(*m_.cycle_z, 4) + (m_.absolute ? "" : " (G91: Z from R)") +
                       ": it would drill upwards; LinuxCNC stops on it (\"R less than z in cycle "
                       "in xy plane\")");
        const double repeats = line.value('L').value_or(1);
        if (!(repeats >= 0 && repeats <= 10000 && repeats == std::floor(repeats)))
            throw fail("canned cycle " + code.text() + " L" + number(repeats, 3) +
                       ": L repeats a hole 0 to 10000 times");
        const bool keep = frame_.flavour == Flavour::linuxcnc;
        if (!m_.xy_known && !(m_.absolute && line.has('X') && line.has('Y') && !polar.any()))
            throw fail(
                "a drilling cycle where the position is unknown (after G28 or at the start)");
        const Point2 offset = offset_or_fail("a drilling cycle");
        // The planes in the job's frame, mm, fixed for the block: G91 takes R from the height
        // the series of cycles started at (as LinuxCNC reads it: a later block's R0 is that
        // height again, not the retract it starts from), Z from R.
        std::optional<double> r_mm, bottom_mm;
        if (m_.absolute) {
            r_mm = *m_.cycle_r * m_.unit_mm;
            bottom_mm = *m_.cycle_z * m_.unit_mm;
        } else if (m_.cycle_start_z_mm) {
            r_mm = *m_.cycle_start_z_mm + *m_.cycle_r * m_.unit_mm;
            bottom_mm = *r_mm + *m_.cycle_z * m_.unit_mm;
        } else if (!keep) {
            throw fail("canned cycle " + code.text() +
                       " in incremental mode (G91) from a height the file does not give: give a "
                       "Z move before it");
        }
        std::optional<double> clear_mm = r_mm;
        if (!m_.retract_to_r)
            clear_mm = m_.cycle_start_z_mm && r_mm
                           ? std::optional<double>(std::max(*m_.cycle_start_z_mm, *r_mm))
                           : std::nullopt;
        const CommandWords commands = command_words(line);
        for (long k = 0; k < static_cast<long>(repeats); ++k) {
            const Point2 hole = end_of(line, polar, offset);
            inside_travel(hole, offset);
            const Point2 c = corrected(hole);
            if (keep) {
                std::string text;
                if (k == 0)
                    for (const Code kc : kept_codes) text += kc.text() + " ";
                text += code.text();
                text += xy_words(c, offset, decimals());
                // R stays in force from block to block, as the job's own repeats keep it (under
                // G91 it is taken from the series' start either way).
                if (k == 0 && line.has('R')) text += " R" + number(*line.value('R'), 6);
                text += other_words(line, k == 0 ? "XYRLGM" : "XYRLGFM");
                if (k == 0) text += commands.before;
                if (k + 1 == static_cast<long>(repeats))
                    text += commands.after + trailing_comment(raw);
                emit(text);
            } else {
                if (k == 0 && !commands.before.empty()) emit(commands.before.substr(1));
                // Written out in absolute coordinates; an incremental job goes back to G91.
                const bool incremental = !m_.absolute;
                if (incremental) emit("G90"), m_.absolute = true;
                written_out_cycle(c, offset, *r_mm, *bottom_mm, clear_mm, line, kept_codes, k == 0);
                if (incremental) emit("G91"), m_.absolute = false;
                if (k + 1 == static_cast<long>(repeats) && !commands.after.empty())
                    emit(commands.after.substr(1));
                if (k + 1 == static_cast<long>(repeats)) {
                    const std::string comment = gcode::comments_of(gcode::without_checksum(raw));
                    if (!comment.empty()) emit(comment);
                }
            }
            ++report_.holes;
            ++report_.pieces;
            m_.xy_mm = hole;
            m_.xy_known = true;
            m_.z_mm = clear_mm;
            m_.written_z.reset();
        }
        if (repeats == 0) verbatim(raw);
    }

    // A hole as moves, for a controller without canned cycles (grbl, printers' firmware).
    void written_out_cycle(Point2 c, Point2 offset, double r_mm, double bottom_mm,
                           std::optional<double> clear_mm, const gcode::Line& line,
                           const std::vector<Code>& kept_codes, bool first) {
        const Code code{m_.motion, -1};
        if (!clear_mm)
            throw fail("canned cycle " + code.text() +
                       " under G98 returns to the height before the cycles, which the file does "
                       "not give: have the CAM write G99, or a Z move before it");
        const int d = decimals();
        const auto z = [&](double mm) { return " Z" + number(mm / m_.unit_mm, d); };
        std::string head;
        if (first)
            for (const Code kc : kept_codes)
                // G91 is written after the hole, which is written in G90.
                if (!kc.is(98) && !kc.is(99) && !kc.is(91)) head += kc.text() + " ";
        // The block's F is set on its first line, before any of its moves, as the cycle set it.
        std::string feed;
        if (auto f = line.value('F'); f && first) feed = " F" + number(*f, 6);
        if (m_.z_mm && *m_.z_mm < r_mm)
            emit(head + "G0" + z(r_mm) + feed), head.clear(), feed.clear();
        emit(head + "G0" + xy_words(c, offset, d) + feed);
        if (!m_.z_mm || *m_.z_mm != r_mm) emit("G0" + z(r_mm));
        const auto down = [&](double to_mm) { emit("G1" + z(to_mm)); };
        const double peck_clearance_mm = 0.254;  // LinuxCNC's: 0.010 inch
        switch (m_.motion) {
            case 81:
                down(bottom_mm);
                break;
            case 82:
            case 89:
                down(bottom_mm);
                emit("G4 P" + number(m_.cycle_p.value_or(0), 4));
                if (m_.motion == 89) emit("G1" + z(r_mm));
                break;
            case 85:
                down(bottom_mm);
                emit("G1" + z(r_mm));
                break;
            case 73:
            case 83: {
                const double q_mm = m_.cycle_q.value_or(0) * m_.unit_mm;
                if (!(q_mm > 0))
                    throw fail("canned cycle " + code.text() + " needs a peck depth Q above 0");
                double depth = r_mm;
                while (depth > bottom_mm + 1e-9) {
                    const double next = std::max(depth - q_mm, bottom_mm);
                    if (depth < r_mm && m_.motion == 83) emit("G0" + z(depth + peck_clearance_mm));
                    down(next);
                    depth = next;
                    if (depth > bottom_mm + 1e-9)
                        emit("G0" + z(m_.motion == 83 ? r_mm : depth + peck_clearance_mm));
                }
                break;
            }
            default:
                throw fail("canned cycle " + code.text() +
                           " (tapping, boring with a spindle stop, back boring or a manual "
                           "retract) on a controller without cycles: have the CAM write it out");
        }
        emit("G0" + z(*clear_mm));
    }

    const MachineCorrection& correction_;
    const JobFrame& frame_;
    const CompensateSettings& settings_;
    CompensateReport& report_;
    Modal m_;
    Numbering numbering_;
    std::string out_;
    long line_number_ = 0;
    bool numbered_ = false, checksummed_ = false, machine_move_ = false;
    int motion_before_ = -1;  // the motion in force before the line being read
    // An offset line as the controller must read it, where calbox rewrote it (G92, G10 L20).
    std::optional<std::string> rewritten_;
    double written_precision_ = 1;  // the job's units: 0.001 for a file written to 3 decimals
};

}  // namespace

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

std::string compensate_scanner_csv(std::string_view job, const MachineCorrection& correction,
                                   const JobFrame& frame, const CompensateSettings& settings,
                                   CompensateReport& report) {
    if (!(settings.max_segment_mm > 0))
        throw CompensateError("the segment length must be positive");
    if (!frame.work_zero_mm[0])
        throw CompensateError("the scanner job's zero on the machine is not known");
    if (frame.turn_rad != 0 || frame.scale != 1)
        throw CompensateError("a scanner job is not placed turned: its field is the machine's");
    const Point2 zero = *frame.work_zero_mm[0];
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
        const Point2 to{x + zero.x, y + zero.y};
        if (!frame.travel_mm.contains(to))
            throw CompensateError("line " + std::to_string(number_of_line) + ": the point " +
                                  number(x, 4) + "," + number(y, 4) +
                                  " is beyond the field the machine reaches");
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
            const Point2 c = held_correction(correction, p, report);
            std::snprintf(line, sizeof line, "%.4f,%.4f,%s\n", c.x - zero.x, c.y - zero.y,
                          number(power, 3).c_str());
            out += line;
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

}  // namespace calbox::targets
