#include "core/gcode/gcode_line.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>

namespace calbox::gcode {
namespace {

bool is_blank(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n';
}

}  // namespace

std::optional<CommandNumber> command_number_of(char letter, double value) {
    // The range is checked before the conversion, which is undefined outside int. A G code may
    // have one decimal (G92.1, G38.2, G61.1).
    if (!(value >= 0 && value < 10000)) return std::nullopt;
    const double whole = std::floor(value);
    const double tenths = std::round((value - whole) * 10);
    if ((letter != 'G' && whole != value) || std::abs((value - whole) * 10 - tenths) > 1e-6)
        return std::nullopt;
    return CommandNumber{static_cast<int>(whole), tenths > 0 ? static_cast<int>(tenths) : -1};
}

std::vector<std::string_view> lines_of_job(std::string_view job) {
    std::vector<std::string_view> lines;
    std::size_t start = 0;
    while (start < job.size()) {
        const auto end = job.find('\n', start);
        if (end == std::string_view::npos) {
            lines.push_back(job.substr(start));
            break;
        }
        lines.push_back(job.substr(start, end - start));
        start = end + 1;
    }
    return lines;
}

std::string strip_comments(std::string_view raw) {
    std::string out;
    out.reserve(raw.size());
    bool in_paren = false;
    for (char c : raw) {
        if (in_paren) {
            if (c == ')') in_paren = false;
            continue;
        }
        if (c == ';') break;
        if (c == '(') {
            in_paren = true;
            continue;
        }
        out.push_back(c);
    }
    if (in_paren) throw SyntaxError("unclosed '(' comment");
    std::size_t first = 0;
    while (first < out.size() && is_blank(out[first])) ++first;
    std::size_t last = out.size();
    while (last > first && is_blank(out[last - 1])) --last;
    if (last == first + 1 && out[first] == '%') return {};
    return out;
}

std::string cnc_words(std::string_view raw, std::string_view letters) {
    std::string out;
    std::size_t i = 0;
    const auto column = [&](std::size_t at) { return "column " + std::to_string(at + 1) + ": "; };
    // Past blanks and comments, to the next character that counts (or the end).
    const auto next = [&] {
        while (i < raw.size()) {
            if (is_blank(raw[i])) {
                ++i;
            } else if (raw[i] == '(') {
                const auto close = raw.find(')', i);
                if (close == std::string_view::npos)
                    throw SyntaxError(column(i) + "a '(' comment not closed on its line");
                i = close + 1;
            } else if (raw[i] == ';') {
                i = raw.size();
            } else {
                break;
            }
        }
        return i < raw.size();
    };
    const auto is_digit = [](char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; };
    // A program's opening and closing '%', alone on its line.
    if (next() && raw[i] == '%') {
        ++i;
        if (!next()) return out;
        throw SyntaxError(column(i) + "words after a program's '%' on its line");
    }
    if (next() && raw[i] == '/') {
        out += '/';
        ++i;
    }
    while (next()) {
        const std::size_t at = i;
        const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(raw[i])));
        if (!std::isalpha(static_cast<unsigned char>(letter)))
            throw SyntaxError(column(at) + "'" + std::string(1, raw[i]) +
                              "' where a word's letter should be");
        if (letters.find(letter) == std::string_view::npos)
            throw SyntaxError(column(at) + "'" + std::string(1, raw[i]) +
                              "': the controller has no " + std::string(1, letter) + " word");
        ++i;
        // Blanks count for nothing inside a word, but a comment ends it: LinuxCNC reads
        // 'X1(c)9' as X1 and then a stray '9' ("Bad character '9' used") where grbl, which drops
        // comments as it reads, would take X19. Refused rather than read either way.
        const auto blanks = [&] {
            while (i < raw.size() && is_blank(raw[i])) ++i;
            return i < raw.size();
        };
        std::string number;
        bool digits = false, point = false;
        if (blanks() && (raw[i] == '+' || raw[i] == '-')) number += raw[i++];
        while (blanks() && (is_digit(raw[i]) || (raw[i] == '.' && !point))) {
            point = point || raw[i] == '.';
            digits = digits || is_digit(raw[i]);
            number += raw[i++];
        }
        const std::string word = std::string(1, letter) + number;
        if (!digits && i < raw.size() && (raw[i] == '(' || raw[i] == ';'))
            throw SyntaxError(column(i) + "a comment between '" + word +
                              "' and its number (the controller reads no number there)");
        if (!digits)
            throw SyntaxError(column(at) + "'" + word + "': " + std::string(1, letter) +
                              " without a number after it");
        if (blanks() && raw[i] != '(' && raw[i] != ';' &&
            !std::isalpha(static_cast<unsigned char>(raw[i])))
            throw SyntaxError(column(at) + "'" + word + std::string(1, raw[i]) + "': '" +
                              std::string(1, raw[i]) + "' is no part of a number");
        if (!out.empty() && out != "/") out += ' ';
        out += word;
    }
    return out;
}

std::string comments_of(std::string_view raw) {
    std::string out;
    for (std::size_t i = 0; i < raw.size(); ++i) {
        std::size_t end = std::string_view::npos;
        if (raw[i] == ';') {
            end = raw.size();
        } else if (raw[i] == '(') {
            end = raw.find(')', i);
            end = end == std::string_view::npos ? raw.size() : end + 1;
        } else {
            continue;
        }
        std::string_view comment = raw.substr(i, end - i);
        while (!comment.empty() && is_blank(comment.back())) comment.remove_suffix(1);
        if (!out.empty()) out += ' ';
        out += comment;
        i = end - 1;
    }
    return out;
}

std::uint8_t checksum(std::string_view text) {
    std::uint8_t sum = 0;
    for (char c : text) sum ^= static_cast<std::uint8_t>(c);
    return sum;
}

std::string numbered_line(long number, std::string_view command) {
    // Appended piece by piece: GCC 12 at -O3 warns (-Wrestrict, a false positive) on
    // "N" + std::to_string(...).
    std::string body(1, 'N');
    body += std::to_string(number);
    body += ' ';
    body += command;
    return body + "*" + std::to_string(checksum(body));
}

namespace {

// Where the checksum's '*' is: the first outside a comment, or npos.
std::size_t checksum_star(std::string_view line) {
    bool in_paren = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
        const char c = line[i];
        if (in_paren) {
            in_paren = c != ')';
            continue;
        }
        if (c == ';') return std::string_view::npos;
        if (c == '(') in_paren = true;
        if (c == '*') return i;
    }
    return std::string_view::npos;
}

std::string_view verify_checksum(std::string_view line) {
    const auto star = checksum_star(line);
    if (star == std::string_view::npos) return line;
    const std::uint8_t sum = checksum(line.substr(0, star));
    auto digits = line.substr(star + 1);
    while (!digits.empty() && is_blank(digits.back())) digits.remove_suffix(1);
    unsigned expected = 0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), expected);
    if (ec != std::errc() || end != digits.data() + digits.size() || digits.empty()) {
        throw SyntaxError("bad checksum '" + std::string(digits) + "'");
    }
    if (expected != sum) {
        throw SyntaxError("checksum mismatch: line says " + std::to_string(expected) +
                          ", computed " + std::to_string(sum));
    }
    return line.substr(0, star);
}

}  // namespace

std::string_view without_checksum(std::string_view raw) {
    return raw.substr(0, checksum_star(raw));
}

bool Line::has(char letter) const {
    for (const auto& w : parameters)
        if (w.letter == letter) return true;
    return false;
}

std::optional<double> Line::value(char letter) const {
    for (const auto& w : parameters)
        if (w.letter == letter) return w.value;
    return std::nullopt;
}

std::vector<double> Line::values(char letter) const {
    for (const auto& w : parameters)
        if (w.letter == letter) {
            if (!w.list.empty()) return w.list;
            if (w.value) return {*w.value};
            return {};
        }
    return {};
}

namespace {

// A word's number: one, or RepRapFirmware's ':'-separated list of them (`list` then holds every
// element, `value` the first).
void read_word_number(std::string_view number, char letter, std::optional<double>& value,
                      std::vector<double>& list) {
    for (std::size_t from = 0; from < number.size();) {
        const std::size_t colon = std::min(number.find(':', from), number.size());
        const std::string_view element = number.substr(from, colon - from);
        double v = 0;
        const char* first = element.data();
        if (!element.empty() && *first == '+') ++first;
        const auto [end, ec] = std::from_chars(first, element.data() + element.size(), v);
        if (element.empty() || ec != std::errc() || end != element.data() + element.size()) {
            throw SyntaxError(std::string("bad number '") + std::string(number) + "' after " +
                              letter);
        }
        if (!value)
            value = v;
        else {
            if (list.empty()) list.push_back(*value);
            list.push_back(v);
        }
        from = colon + 1;
        if (colon + 1 == number.size()) {
            throw SyntaxError(std::string("bad number '") + std::string(number) + "' after " +
                              letter);
        }
    }
}

}  // namespace

Line parse_line(std::string_view raw) {
    // The checksum covers the raw text before '*', comments included.
    const std::string body = strip_comments(verify_checksum(raw));
    Line line;
    std::size_t i = 0;
    const auto skip_blanks = [&] {
        while (i < body.size() && is_blank(body[i])) ++i;
    };
    skip_blanks();
    if (i < body.size() && body[i] == '/') {
        line.block_delete = true;
        ++i;
    }
    while (true) {
        skip_blanks();
        if (i >= body.size()) break;
        const char letter = static_cast<char>(std::toupper(static_cast<unsigned char>(body[i])));
        if (!std::isalpha(static_cast<unsigned char>(letter))) {
            throw SyntaxError(std::string("unexpected character '") + body[i] + "'");
        }
        ++i;
        const std::size_t start = i;
        while (i < body.size() && !is_blank(body[i]) &&
               !std::isalpha(static_cast<unsigned char>(body[i]))) {
            ++i;
        }
        const std::string_view number(body.data() + start, i - start);
        std::optional<double> value;
        std::vector<double> list;
        read_word_number(number, letter, value, list);
        const bool one_value = value && list.empty();
        if (letter == 'N' && line.command_letter == 0 && !line.line_number) {
            // Hosts number lines from 0 upwards in a signed 32-bit counter.
            if (!one_value || !(*value >= 0 && *value <= 2147483647.0) ||
                *value != std::floor(*value)) {
                throw SyntaxError("line number N without one whole value from 0 to 2147483647");
            }
            line.line_number = static_cast<long>(*value);
            continue;
        }
        if (line.command_letter == 0 && (letter == 'G' || letter == 'M' || letter == 'T')) {
            const auto command = one_value ? command_number_of(letter, *value) : std::nullopt;
            if (!command) throw SyntaxError(std::string("bad command number after ") + letter);
            line.command_letter = letter;
            line.command_number = command->number;
            line.command_subcode = command->subcode;
            if (line.is('M', 117) || line.is('M', 118)) {
                skip_blanks();
                line.text = body.substr(i);
                while (!line.text.empty() && is_blank(line.text.back())) line.text.pop_back();
                break;
            }
            continue;
        }
        line.parameters.push_back(Word{letter, value, std::move(list)});
    }
    return line;
}

}  // namespace calbox::gcode
