#include "core/targets/job_words.hpp"

#include <cmath>
#include <cstdio>

#include "core/number_text.hpp"

namespace calbox::targets::job_words {

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

}  // namespace calbox::targets::job_words
