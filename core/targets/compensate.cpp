#include "core/targets/compensate.hpp"

#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>

#include "core/targets/gcode_line.hpp"

namespace calbox::targets {
namespace {

using geometry::Point2;

constexpr double kPi = 3.14159265358979323846;

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

struct Machine {
    bool absolute_xy = true, absolute_e = true;
    Point2 xy;
    bool xy_known = false;  // not until a move gives both axes (and not after G28)
    std::optional<double> z;
    double e = 0;
};

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

}  // namespace

std::string compensate_gcode(std::string_view job, const Correction& correct, const Covers& covers,
                             const CompensateSettings& settings, CompensateReport& report) {
    if (!(settings.max_segment_mm > 0) || !(settings.arc_tolerance_mm > 0))
        throw CompensateError("the segment length and arc tolerance must be positive");
    Writer writer(correct, covers, report);
    Machine m;
    std::string out;
    std::size_t start = 0;
    long number_of_line = 0;
    while (start <= job.size()) {
        const auto end = job.find('\n', start);
        const bool last = end == std::string_view::npos;
        const std::string_view raw = job.substr(start, last ? std::string_view::npos : end - start);
        start = last ? job.size() + 1 : end + 1;
        if (last && raw.empty()) break;
        ++number_of_line;
        ++report.lines;
        const auto fail = [&](const std::string& why) -> CompensateError {
            return CompensateError("line " + std::to_string(number_of_line) + ": " + why);
        };
        gcode::Line line;
        try {
            line = gcode::parse_line(raw);
        } catch (const gcode::SyntaxError& e) {
            throw fail(e.what());
        }
        if (line.line_number || raw.find('*') != std::string_view::npos)
            throw fail(
                "numbered or checksummed lines: compensate the job before a host numbers it");
        const auto verbatim = [&] {
            out += raw;
            out += '\n';
        };
        if (line.command_letter == 'G') {
            switch (line.command_number) {
                case 90:
                    m.absolute_xy = true;
                    break;
                case 91:
                    m.absolute_xy = false;
                    break;
                case 20:
                    throw fail("inches (G20): calbox compensates jobs in millimetres");
                case 18:
                case 19:
                    throw fail("arcs off the XY plane (G18 / G19) cannot be compensated");
                case 92:
                    if (line.has('X') || line.has('Y'))
                        throw fail("G92 with X or Y moves the job's origin: not compensated");
                    if (auto e = line.value('E')) m.e = *e;
                    if (auto z = line.value('Z')) m.z = *z;
                    break;
                case 28:
                    m.xy_known = false, m.z.reset();
                    break;
                default:
                    break;
            }
        } else if (line.is('M', 82)) {
            m.absolute_e = true;
        } else if (line.is('M', 83)) {
            m.absolute_e = false;
        }
        const bool move =
            line.command_letter == 'G' && line.command_number >= 0 && line.command_number <= 3;
        const bool arc = line.command_number == 2 || line.command_number == 3;
        if (!move || !(line.has('X') || line.has('Y') || arc)) {
            if (move && line.has('Z')) {
                if (auto z = line.value('Z')) m.z = m.absolute_xy ? *z : m.z.value_or(0) + *z;
            }
            if (move && line.has('E')) {
                if (auto e = line.value('E')) m.e = m.absolute_e ? *e : m.e + *e;
            }
            verbatim();
            continue;
        }
        if (!m.absolute_xy)
            throw fail("relative XY moves (G91) cannot be compensated: write the job in G90");
        if (!m.xy_known && !(line.has('X') && line.has('Y')))
            throw fail(
                "a move that gives one axis where the other's position is unknown (after G28 or at "
                "the start)");
        const Point2 from = m.xy;
        const Point2 to{line.value('X').value_or(from.x), line.value('Y').value_or(from.y)};
        const std::optional<double> z_from = m.z;
        const std::optional<double> z_to = line.value('Z') ? line.value('Z') : m.z;
        const std::optional<double> e_word = line.value('E');
        // The path's points, from the start (excluded) to the end.
        std::vector<Point2> path;
        if (arc) {
            if (!m.xy_known) throw fail("an arc needs a known start");
            ++report.arcs;
            Point2 centre;
            if (line.has('R')) {
                const double r = line.value('R').value_or(0);
                const double dx = to.x - from.x, dy = to.y - from.y, chord = std::hypot(dx, dy);
                if (!(std::abs(r) >= chord / 2 - 1e-9) || chord == 0)
                    throw fail("the arc's radius R is shorter than half its chord");
                const double h = std::sqrt(std::max(0.0, r * r - chord * chord / 4));
                // G2 (clockwise) with R > 0 takes the short way: the centre to the chord's right.
                const double side = (line.command_number == 2 ? 1 : -1) * (r > 0 ? 1 : -1);
                centre = {from.x + dx / 2 + side * h * dy / chord,
                          from.y + dy / 2 - side * h * dx / chord};
            } else {
                if (!line.has('I') && !line.has('J')) throw fail("an arc needs I and J, or R");
                centre = {from.x + line.value('I').value_or(0),
                          from.y + line.value('J').value_or(0)};
            }
            const double radius = std::hypot(from.x - centre.x, from.y - centre.y);
            const double a0 = std::atan2(from.y - centre.y, from.x - centre.x);
            const double a1 = std::atan2(to.y - centre.y, to.x - centre.x);
            const bool clockwise = line.command_number == 2;
            double sweep = a1 - a0;
            if (clockwise) {
                while (sweep >= -1e-12) sweep -= 2 * kPi;
            } else {
                while (sweep <= 1e-12) sweep += 2 * kPi;
            }
            if (std::hypot(to.x - from.x, to.y - from.y) < 1e-9 && !line.has('R'))
                sweep = clockwise ? -2 * kPi : 2 * kPi;  // a whole circle
            const double by_tolerance = radius > settings.arc_tolerance_mm
                                            ? 2 * std::acos(1 - settings.arc_tolerance_mm / radius)
                                            : kPi;
            const double by_length = settings.max_segment_mm / std::max(radius, 1e-9);
            const int pieces = std::max(
                1,
                static_cast<int>(std::ceil(std::abs(sweep) / std::min(by_tolerance, by_length))));
            for (int k = 1; k <= pieces; ++k) {
                const double a = a0 + sweep * k / pieces;
                path.push_back(k == pieces ? to
                                           : Point2{centre.x + radius * std::cos(a),
                                                    centre.y + radius * std::sin(a)});
            }
        } else {
            const double length = m.xy_known ? std::hypot(to.x - from.x, to.y - from.y) : 0;
            const int pieces =
                std::max(1, static_cast<int>(std::ceil(length / settings.max_segment_mm)));
            for (int k = 1; k <= pieces; ++k)
                path.push_back(k == pieces ? to
                                           : Point2{from.x + (to.x - from.x) * k / pieces,
                                                    from.y + (to.y - from.y) * k / pieces});
        }
        ++report.moves;
        const std::string command = arc ? "G1" : (line.command_number == 0 ? "G0" : "G1");
        const double e_from = m.e;
        const double e_total = e_word ? (m.absolute_e ? *e_word - m.e : *e_word) : 0;
        const std::size_t n = path.size();
        for (std::size_t k = 0; k < n; ++k) {
            const double share = static_cast<double>(k + 1) / static_cast<double>(n);
            const Point2 c = writer.corrected(path[k]);
            std::string text = command + " X" + number(c.x, 4) + " Y" + number(c.y, 4);
            if (line.has('Z') && z_to) {
                const double z = z_from ? *z_from + (*z_to - *z_from) * share : *z_to;
                text += " Z" + number(z, 4);
            }
            if (e_word) {
                text += " E" + number(m.absolute_e ? e_from + e_total * share
                                                   : e_total / static_cast<double>(n),
                                      5);
            }
            if (k == 0) {
                for (const auto& w : line.parameters) {
                    if (w.letter == 'X' || w.letter == 'Y' || w.letter == 'Z' || w.letter == 'E' ||
                        w.letter == 'I' || w.letter == 'J' || w.letter == 'R')
                        continue;
                    text += ' ';
                    text += w.letter;
                    if (w.value) text += number(*w.value, 6);
                }
            }
            if (k + 1 == n) {
                const std::string comment = comment_of(raw);
                if (!comment.empty()) text += " " + comment;
            }
            out += text + '\n';
            ++report.pieces;
        }
        m.xy = to;
        m.xy_known = true;
        m.z = z_to;
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
