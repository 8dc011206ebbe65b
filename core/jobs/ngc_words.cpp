#include "core/jobs/ngc_words.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>

#include "core/jobs/ngc_program.hpp"

namespace calbox::gcode::ngc {

char upper(char c) {
    return static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
}
bool is_blank(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n';
}

SplitLine split_comments(std::string_view raw, long number) {
    SplitLine s;
    bool in_paren = false;
    for (std::size_t i = 0; i < raw.size(); ++i) {
        const char c = raw[i];
        if (in_paren) {
            s.comment += c;
            if (c == ')') in_paren = false;
            continue;
        }
        if (c == ';') {
            s.comment += raw.substr(i);
            break;
        }
        if (c == '(') {
            in_paren = true;
            s.comment += c;
            continue;
        }
        if (c != '\r') s.code += c;
    }
    if (in_paren) throw ProgramError("line " + std::to_string(number) + ": unclosed '(' comment");
    while (!s.comment.empty() && (s.comment.back() == '\r' || s.comment.back() == '\n'))
        s.comment.pop_back();
    return s;
}

// A number as plain G-code writes it: no exponent, trailing zeros dropped; ten decimals keep a
// computed value far finer than any machine's resolution.
std::string plain_number(double v) {
    if (std::abs(v) < 5e-11) return "0";
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.10f", v);
    std::string s = buffer;
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
    return s;
}

// Parameter names are read as LinuxCNC reads them: case and blanks do not count.
std::string normal_name(std::string_view name) {
    std::string out;
    for (char c : name)
        if (!is_blank(c)) out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

namespace {

// The O-word's label at code[i] ("<name>" or a number), `i` past it; nothing for neither.
std::optional<std::string> o_label_at(const std::string& code, std::size_t& i) {
    if (i < code.size() && code[i] == '<') {
        const auto close = code.find('>', i);
        if (close == std::string::npos) return std::nullopt;
        // Appended, not "<" + name: GCC 12 at -O3 reads the prepend as an overlapping copy.
        std::string label(1, '<');
        label += normal_name(code.substr(i + 1, close - i - 1));
        label += '>';
        i = close + 1;
        return label;
    }
    std::size_t j = i;
    while (j < code.size() && (std::isdigit(static_cast<unsigned char>(code[j])) != 0)) ++j;
    if (j == i) return std::nullopt;
    long value = 0;
    std::from_chars(code.data() + i, code.data() + j, value);
    i = j;
    return std::to_string(value);  // o0100 is o100
}

}  // namespace

std::optional<OWord> o_word_of(const std::string& code) {
    std::size_t i = 0;
    const auto skip = [&] {
        while (i < code.size() && is_blank(code[i])) ++i;
    };
    skip();
    if (i < code.size() && code[i] == '/') ++i, skip();
    if (i < code.size() && upper(code[i]) == 'N') {  // a line number before the O-word
        std::size_t j = i + 1;
        while (j < code.size() && (std::isdigit(static_cast<unsigned char>(code[j])) != 0)) ++j;
        if (j > i + 1) i = j, skip();
    }
    if (i >= code.size() || upper(code[i]) != 'O') return std::nullopt;
    ++i;
    skip();
    OWord o;
    auto label = o_label_at(code, i);
    if (!label) return std::nullopt;
    o.label = std::move(*label);
    skip();
    std::size_t j = i;
    while (j < code.size() && (std::isalpha(static_cast<unsigned char>(code[j])) != 0)) ++j;
    o.keyword = normal_name(code.substr(i, j - i));
    // A bare O number is a program's number (Fanuc's "O1234"), no control word.
    if (o.keyword.empty()) return std::nullopt;
    o.rest = code.substr(j);
    return o;
}

}  // namespace calbox::gcode::ngc
