// What each controller reads: its letters, its G and M codes and their modal groups, the codes
// calbox refuses and why; a line's text (its body, polar words, written precision).
#include <algorithm>
#include <cctype>
#include <charconv>
#include <string>

#include "core/jobs/compensator.hpp"
#include "core/number_text.hpp"

namespace calbox::jobs::compensating {

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

bool dwells_at_bottom(int motion) {
    return motion == 82 || motion == 86 || motion == 88 || motion == 89;
}

namespace {

// The number after the polar word's letter at raw[i] (spaces between them allowed), and where it
// ends; throws gcode::SyntaxError for a bad one.
std::pair<double, std::size_t> polar_number_after(const std::string& raw, std::size_t i) {
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
        throw gcode::SyntaxError(std::string("bad number after '") + raw[i] + "'");
    return {v, k};
}

}  // namespace

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
        const auto [v, k] = polar_number_after(raw, i);
        (c == '@' ? polar.distance : polar.angle_deg) = v;
        raw.erase(i, k - i);
        --i;
    }
    return polar;
}

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

bool is_lathe_word(const Code& c) {
    return c.is(7) || c.is(8) || c.is(76) || (c.number >= 70 && c.number <= 72 && c.subcode < 0);
}

bool is_cnc(Flavour f) {
    return f != Flavour::printer;
}

std::string_view letters_of(Flavour f) {
    return f == Flavour::linuxcnc ? "ABCDFGHIJKLMNPQRSTUVWXYZ" : "ABCDFGHIJKLMNPQRSTXYZ";
}

std::string controller_of(Flavour f) {
    return f == Flavour::linuxcnc ? "LinuxCNC" : f == Flavour::grbl ? "grbl" : "the printer";
}

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

}  // namespace calbox::jobs::compensating
