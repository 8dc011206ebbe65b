// The rules of each controller's reader that a line must keep before calbox writes it: its words,
// its comments, one code per modal group, words no code uses, values that cannot be negative.
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "core/jobs/compensator.hpp"
#include "core/number_text.hpp"

namespace calbox::jobs::compensating {

void Compensator::refuse_nested_comment(std::string_view raw) {
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

std::string Compensator::words_of(const std::string& raw, Polar* polar,
                                  std::string_view more_letters) const {
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

void Compensator::check_m_word(double value) const {
    const std::string who = controller_of(frame_.flavour);
    if (value != std::floor(value))
        throw fail("M" + number(value, 4) + ": an M code is a whole number (" + who +
                   " stops on it" +
                   (frame_.flavour == Flavour::grbl ? ": its error 20)"
                                                    : ": \"Non integer value for integer\")"));
    if (!is_known_m(frame_.flavour, value))
        throw fail(
            "M" + number(value, 0) + ": no such M code on " + who + " (it stops on it" +
            (frame_.flavour == Flavour::grbl ? ": its error 20)" : ": \"Unknown m code used\")"));
}

void Compensator::refuse_repeated_words(const gcode::Line& line,
                                        const std::vector<Code>& codes) const {
    const std::string stops = ": " + controller_of(frame_.flavour) + " stops on it";
    std::array<int, 256> seen{};
    if (line.command_letter == 'T') ++seen['T'];
    for (const auto& w : line.parameters)
        if (w.letter != 'G' && w.letter != 'M' && ++seen[static_cast<unsigned char>(w.letter)] == 2)
            throw fail(std::string("two ") + w.letter + " words on one line" + stops);
    for (std::size_t i = 0; i < codes.size(); ++i)
        for (std::size_t j = i + 1; j < codes.size(); ++j)
            if (modal_group(codes[i]) >= 0 && modal_group(codes[i]) == modal_group(codes[j]))
                throw fail("two G codes of one modal group on one line (" + codes[i].text() +
                           " and " + codes[j].text() + ")" + stops);
}

void Compensator::word_rules(const gcode::Line& line, const std::vector<Code>& codes) const {
    for (const Code c : codes)
        if (!is_known_code(c))
            throw fail(c.text() + ": no such G code (" + controller_of(frame_.flavour) +
                       " stops on it: \"Unknown g code used\")");
    if (line.command_letter == 'M') check_m_word(line.command_number);
    for (const auto& w : line.parameters)
        if (w.letter == 'M' && w.value) check_m_word(*w.value);
    refuse_repeated_words(line, codes);
}

void Compensator::refuse_off_plane_arc_word(const gcode::Line& line) const {
    const char other = m_.plane == 17 ? 'K' : m_.plane == 18 ? 'J' : 'I';
    const char* plane = m_.plane == 17 ? "XY" : m_.plane == 18 ? "XZ" : "YZ";
    if (line.has(other))
        throw fail(std::string(1, other) + " word in an arc in the " + plane +
                   " plane: " + controller_of(frame_.flavour) + " stops on it");
}

void Compensator::unused_words(const gcode::Line& line, const std::vector<Code>& codes,
                               int motion) const {
    const auto stops = [this] { return ": " + controller_of(frame_.flavour) + " stops on it"; };
    const auto on_line = [&](int number) {
        return std::any_of(codes.begin(), codes.end(),
                           [number](Code c) { return c.number == number; });
    };
    const bool arc = motion == 2 || motion == 3, cycle = is_cycle(motion);
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
    if (arc) refuse_off_plane_arc_word(line);
    if (!arc && !cycle && !g10) unused('R', "G2, G3, a drilling cycle or G10");
    if (!cycle && !g10) unused('L', "G10 or drilling cycle");
    const bool m_with_p = has_m_in(line, 50, 53) || has_m_in(line, 62, 66) || has_m(line, 98) ||
                          has_m_in(line, 100, 199);
    const bool arc_turns = arc && frame_.flavour == Flavour::linuxcnc;
    if (!on_line(4) && !g10 && !arc_turns && !on_line(64) && !m_with_p && !dwells_at_bottom(motion))
        unused('P', "G4, G10, G64, an arc's turns, G82/G86/G88/G89 or M code");
    if (!(motion == 73 || motion == 83) && !on_line(64) && !g10 && !has_m_in(line, 66, 68) &&
        !has_m_in(line, 100, 199))
        unused('Q', "G73, G83, G64, G10 or M66-M68");
    if (!on_line(43)) unused('H', "G43");
    unused('D', "G41 or G42");
}

void Compensator::cnc_rules(const gcode::Line& line, const std::vector<Code>& codes,
                            bool polar) const {
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
    unused_words(line, codes, motion);
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

void Compensator::negative_words(const gcode::Line& line) const {
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
        throw fail("'" + std::string(1, w.letter) + number(*w.value, 4) + "': a negative " + what +
                   ": " + controller_of(frame_.flavour) + " stops on it" +
                   (grbl ? " (its error 4)" : ""));
    }
}

}  // namespace calbox::jobs::compensating
