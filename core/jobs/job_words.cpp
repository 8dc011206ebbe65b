#include "core/jobs/job_words.hpp"

#include <cmath>
#include <cstdio>

#include "core/number_text.hpp"

namespace calbox::jobs::job_words {

std::string number(double v, int decimals) {
    std::string s = fixed_text(v, decimals);
    if (s.find('.') != std::string::npos) {
        while (s.back() == '0') s.pop_back();
        if (s.back() == '.') s.pop_back();
    }
    if (s == "-0") s = "0";
    return s;
}

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

bool has_m_in(const gcode::Line& line, int from, int to) {
    if (line.command_letter == 'M' && line.command_subcode < 0 && line.command_number >= from &&
        line.command_number <= to)
        return true;
    for (const auto& w : line.parameters)
        if (w.letter == 'M' && w.value && *w.value >= from && *w.value <= to &&
            *w.value == std::floor(*w.value))
            return true;
    return false;
}

bool has_m(const gcode::Line& line, int number) {
    return has_m_in(line, number, number);
}

// LinuxCNC's bound on how far a centre-format arc's end may lie off the circle through its start,
// in the program's units (0.002 sqrt 2 inch; 0.02 sqrt 2 mm): beyond it and beyond 0.1 % of the
// radius, or beyond a hundred times it, rs274 refuses the arc (measured with rs274 itself).
bool arc_end_off_its_circle(double radius_mm, double step_mm, bool inch_job) {
    constexpr double kInchJobMm = 0.002 * 1.41421356237309504880 * 25.4;
    constexpr double kMmJobMm = 0.02 * 1.41421356237309504880;
    const double tolerance_mm = inch_job ? kInchJobMm : kMmJobMm;
    return (step_mm > tolerance_mm && step_mm > 0.001 * radius_mm) || step_mm > 100 * tolerance_mm;
}

bool is_cycle(int motion) {
    return motion == 73 || (motion >= 81 && motion <= 89);
}

CommandWords command_words(const gcode::Line& line) {
    CommandWords words;
    const auto add = [&](char letter, double value) {
        const bool stop =
            letter == 'M' && (value == 0 || value == 1 || value == 2 || value == 30 || value == 60);
        std::string& to = stop ? words.after : words.before;
        char text[32];
        std::snprintf(text, sizeof text, " %c%g", letter, value);
        to += text;
    };
    if (line.command_letter == 'M' || line.command_letter == 'T')
        add(line.command_letter, line.command_number);
    for (const auto& w : line.parameters)
        if (w.letter == 'M' && w.value) add('M', *w.value);
    return words;
}

std::string trailing_comment(const std::string& raw) {
    const std::string comment = gcode::comments_of(gcode::without_checksum(raw));
    return comment.empty() ? std::string() : " " + comment;
}

MoveWords move_words(const std::string& raw, const ReadLine& r, std::string_view taken_out) {
    MoveWords words;
    const auto add = [&words](const std::string& word) {
        if (!words.head.empty()) words.head += ' ';
        words.head += word;
    };
    for (const Code c : r.codes)
        if (!c.is_motion() && c.number != 40 && c.number != 41 && c.number != 42) add(c.text());
    for (const auto& w : r.line.parameters) {
        if (std::string_view("GMXYZN").find(w.letter) != std::string_view::npos ||
            taken_out.find(w.letter) != std::string_view::npos)
            continue;
        if (std::string_view("FST").find(w.letter) == std::string_view::npos) {
            words.other = w.letter;
            return words;
        }
        add(std::string(1, w.letter) + (w.value ? number(*w.value, 6) : std::string()));
    }
    const CommandWords m = command_words(r.line);
    words.head += m.before;
    while (!words.head.empty() && words.head.front() == ' ') words.head.erase(0, 1);
    if (const auto z = r.line.value('Z')) words.tail = " Z" + number(*z, 6);
    words.tail += m.after + trailing_comment(raw);
    return words;
}

std::string rebuilt_line(const std::string& raw, const ReadLine& r, const std::string& extra,
                         std::string_view drop) {
    const gcode::Line& l = r.line;
    std::string text;
    const auto add = [&text](const std::string& word) {
        if (!text.empty()) text += ' ';
        text += word;
    };
    if (l.line_number) add("N" + std::to_string(*l.line_number));
    for (const Code c : r.codes)
        if (c.number != 41 && c.number != 42) add(c.text());
    for (const auto& w : l.parameters) {
        if (std::string_view("GMND").find(w.letter) != std::string_view::npos ||
            drop.find(w.letter) != std::string_view::npos)
            continue;
        add(std::string(1, w.letter) + (w.value ? number(*w.value, 6) : std::string()));
    }
    const CommandWords m = command_words(l);
    text += extra + m.before + m.after + trailing_comment(raw);
    while (!text.empty() && text.front() == ' ') text.erase(0, 1);
    return text;
}

}  // namespace calbox::jobs::job_words
