#include "core/jobs/ngc_program.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <optional>

#include "core/gcode/gcode_line.hpp"
#include "core/jobs/ngc_words.hpp"

namespace calbox::gcode {
namespace {

constexpr int kLocalParameters = 30;  // #1..#30 belong to the subroutine call that set them
// LinuxCNC's parameters from 5000 on are the controller's own (offsets, tool table, position):
// their values are not in the file.
constexpr int kFirstSystemParameter = 5000;

using ngc::is_blank;
using ngc::normal_name;
using ngc::o_word_of;
using ngc::OWord;
using ngc::plain_number;
using ngc::split_comments;
using ngc::SplitLine;
using ngc::upper;

struct Frame {
    std::array<double, kLocalParameters + 1> numbered{};  // #1..#30 of this call
    std::map<std::string, double> named;                  // #<name> without '_': this call's
    std::size_t return_to = 0;                            // the line after the call
    std::string sub;                                      // "" at the top level
};

struct Loop {
    std::string label;
    std::size_t start = 0;  // the loop's opening line
    long turns = 0;
    long repeats_left = -1;  // repeat's count; -1 for while and do
};

class Machine {
  public:
    Machine(std::string_view job, const ProgramLimits& limits) : limits_(limits) {
        for (const std::string_view raw : lines_of_job(job)) {
            raw_.emplace_back(raw);
            split_.push_back(split_comments(raw, static_cast<long>(raw_.size())));
            o_words_.push_back(o_word_of(split_.back().code));
        }
        for (std::size_t i = 0; i < o_words_.size(); ++i)
            if (o_words_[i] && o_words_[i]->keyword == "sub") {
                if (subs_.count(o_words_[i]->label) != 0)
                    throw fail(i, "subroutine o" + o_words_[i]->label + " is defined twice");
                subs_[o_words_[i]->label] = i;
            }
        frames_.emplace_back();
    }

    std::vector<ExecutedLine> run() {
        std::size_t pc = 0;
        long executed = 0;
        while (pc < raw_.size()) {
            if (++executed > limits_.max_executed_lines)
                throw fail(pc, "the program runs past " +
                                   std::to_string(limits_.max_executed_lines) +
                                   " lines: taken for a runaway loop");
            const std::size_t at = pc++;
            if (const auto& o = o_words_[at]) {
                pc = control(at, *o);
                continue;
            }
            const std::string text = evaluated(at);
            // A line of assignments alone leaves nothing to run; a blank line stays blank.
            const bool only_assignments =
                text.empty() && split_[at].code.find_first_not_of(" \t") != std::string::npos;
            if (!only_assignments) out_.push_back({text, static_cast<long>(at + 1)});
            if (ends_program(at)) break;
        }
        return std::move(out_);
    }

  private:
    ProgramError fail(std::size_t at, const std::string& why) const {
        return ProgramError("line " + std::to_string(at + 1) + ": " + why);
    }

    // --- O-words ---------------------------------------------------------------------------

    // The line of the first `keyword` for `label` after `from` (nested uses of other labels
    // skipped as LinuxCNC does: labels are unique within their block).
    std::size_t find_after(std::size_t from, const std::string& label,
                           std::initializer_list<std::string_view> keywords) const {
        for (std::size_t i = from + 1; i < o_words_.size(); ++i) {
            const auto& o = o_words_[i];
            if (!o || o->label != label) continue;
            for (const auto k : keywords)
                if (o->keyword == k) return i;
        }
        std::string names;
        for (const auto k : keywords) names += (names.empty() ? "" : " or ") + std::string(k);
        throw fail(from, "o" + label + " has no " + names + " after it");
    }

    // An endsub or return: back to the line after the call, the value kept in _value.
    std::size_t leave_subroutine(std::size_t at, const OWord& o) {
        const std::string& k = o.keyword;
        if (frames_.size() < 2) {
            if (k == "return") throw fail(at, "o" + o.label + " return outside a subroutine");
            return at + 1;
        }
        if (const auto value = optional_expression(at, o.rest)) globals_["_value"] = *value;
        const std::size_t back = frames_.back().return_to;
        frames_.pop_back();
        // A subroutine's loops end with it.
        while (!loops_.empty() && loop_frames_.back() > frames_.size()) pop_loop();
        return back;
    }

    // A break (past the loop's closer) or a continue (to it).
    std::size_t leave_loop(std::size_t at, const OWord& o) {
        const std::string& k = o.keyword;
        while (!loops_.empty() && loops_.back().label != o.label &&
               loop_frames_.back() == frames_.size())
            pop_loop();
        if (loops_.empty() || loops_.back().label != o.label)
            throw fail(at, "o" + o.label + " " + k + " outside its loop");
        const auto& head = o_words_[loops_.back().start]->keyword;
        const char* closer = head == "repeat" ? "endrepeat" : head == "do" ? "while" : "endwhile";
        const std::size_t end = find_after(loops_.back().start, o.label, {closer});
        if (k == "break") {
            pop_loop();
            return end + 1;
        }
        return end;  // the closer decides whether it turns again
    }

    std::size_t control(std::size_t at, const OWord& o) {
        const std::string& k = o.keyword;
        if (k == "sub") return find_after(at, o.label, {"endsub"}) + 1;  // defined, not run
        if (k == "endsub" || k == "return") return leave_subroutine(at, o);
        if (k == "call") return call(at, o);
        if (k == "if") return branch(at, o);
        if (k == "elseif" || k == "else")  // reached by falling out of a taken branch
            return find_after(at, o.label, {"endif"}) + 1;
        if (k == "endif") return at + 1;
        if (k == "while") {
            // Either a while loop's head or a do loop's tail.
            if (!loops_.empty() && loops_.back().label == o.label &&
                loop_frames_.back() == frames_.size() && o_words_[loops_.back().start] &&
                o_words_[loops_.back().start]->keyword == "do") {
                if (truth(at, o.rest)) return turn(at, loops_.back().start + 1);
                pop_loop();
                return at + 1;
            }
            if (!truth(at, o.rest)) return find_after(at, o.label, {"endwhile"}) + 1;
            push_loop(o.label, at, -1);
            return at + 1;
        }
        if (k == "endwhile") {
            if (loops_.empty() || loops_.back().label != o.label)
                throw fail(at, "o" + o.label + " endwhile without its while");
            const std::size_t head = loops_.back().start;
            if (!truth(head, o_words_[head]->rest)) {
                pop_loop();
                return at + 1;
            }
            return turn(at, head + 1);
        }
        if (k == "do") {
            push_loop(o.label, at, -1);
            return at + 1;
        }
        if (k == "repeat") {
            const double count = expression_only(at, o.rest);
            if (!(count >= 0) || count > static_cast<double>(limits_.max_loop_turns))
                throw fail(at, "o" + o.label + " repeat count " + plain_number(count) +
                                   " is not 0 to " + std::to_string(limits_.max_loop_turns));
            const long n = std::lround(std::floor(count));
            if (n == 0) return find_after(at, o.label, {"endrepeat"}) + 1;
            push_loop(o.label, at, n);
            return at + 1;
        }
        if (k == "endrepeat") {
            if (loops_.empty() || loops_.back().label != o.label)
                throw fail(at, "o" + o.label + " endrepeat without its repeat");
            if (--loops_.back().repeats_left > 0) return turn(at, loops_.back().start + 1);
            pop_loop();
            return at + 1;
        }
        if (k == "break" || k == "continue") return leave_loop(at, o);
        throw fail(at, "unknown O-word keyword '" + k + "'");
    }

    std::size_t call(std::size_t at, const OWord& o) {
        const auto sub = subs_.find(o.label);
        if (sub == subs_.end())
            throw fail(at, "o" + o.label +
                               " call: the subroutine is not in this file (LinuxCNC would look "
                               "for it in its subroutine path); give a program with it in");
        if (static_cast<int>(frames_.size()) > limits_.max_call_depth)
            throw fail(at, "calls nest deeper than " + std::to_string(limits_.max_call_depth));
        Frame f;
        std::size_t i = 0;
        int argument = 0;
        const std::string& rest = o.rest;
        while (true) {
            while (i < rest.size() && is_blank(rest[i])) ++i;
            if (i >= rest.size()) break;
            if (rest[i] != '[')
                throw fail(at, "o" + o.label + " call takes its arguments in '[ ]'");
            const double v = value(at, rest, i);
            if (++argument > kLocalParameters) throw fail(at, "a call takes at most 30 arguments");
            f.numbered[static_cast<std::size_t>(argument)] = v;
        }
        f.return_to = at + 1;
        f.sub = o.label;
        frames_.push_back(f);
        return sub->second + 1;
    }

    std::size_t branch(std::size_t at, const OWord& o) {
        std::size_t i = at;
        bool condition = truth(at, o.rest);
        while (!condition) {
            i = find_after(i, o.label, {"elseif", "else", "endif"});
            const auto& k = o_words_[i]->keyword;
            if (k == "endif" || k == "else") return i + 1;
            condition = truth(i, o_words_[i]->rest);
        }
        return i + 1;
    }

    void push_loop(const std::string& label, std::size_t at, long repeats) {
        loops_.push_back({label, at, 0, repeats});
        loop_frames_.push_back(frames_.size());
    }
    void pop_loop() {
        loops_.pop_back();
        loop_frames_.pop_back();
    }
    std::size_t turn(std::size_t at, std::size_t to) {
        if (++loops_.back().turns >= limits_.max_loop_turns)
            throw fail(at, "o" + loops_.back().label + " turns more than " +
                               std::to_string(limits_.max_loop_turns) +
                               " times: taken for a runaway loop");
        return to;
    }

    bool truth(std::size_t at, const std::string& text) { return expression_only(at, text) != 0; }

    double expression_only(std::size_t at, const std::string& text) {
        std::size_t i = 0;
        while (i < text.size() && is_blank(text[i])) ++i;
        if (i >= text.size() || text[i] != '[') throw fail(at, "expected an expression in '[ ]'");
        const double v = value(at, text, i);
        while (i < text.size() && is_blank(text[i])) ++i;
        if (i != text.size()) throw fail(at, "unexpected '" + text.substr(i) + "'");
        return v;
    }
    std::optional<double> optional_expression(std::size_t at, const std::string& text) {
        if (text.find_first_not_of(" \t") == std::string::npos) return std::nullopt;
        return expression_only(at, text);
    }

    // --- values and expressions ------------------------------------------------------------

    void skip_blanks(const std::string& s, std::size_t& i) const {
        while (i < s.size() && is_blank(s[i])) ++i;
    }

    // A real value: a number, '[expression]', a parameter, a unary function, with a sign.
    double value(std::size_t at, const std::string& s, std::size_t& i) {
        skip_blanks(s, i);
        if (i >= s.size()) throw fail(at, "a value is missing at the end of the line");
        const char c = s[i];
        if (c == '-' || c == '+') {
            ++i;
            const double v = value(at, s, i);
            return c == '-' ? -v : v;
        }
        if (c == '[') {
            ++i;
            const double v = expression(at, s, i);
            skip_blanks(s, i);
            if (i >= s.size() || s[i] != ']') throw fail(at, "an expression lacks its ']'");
            ++i;
            return v;
        }
        if (c == '#') return parameter_value(at, s, i);
        if (std::isalpha(static_cast<unsigned char>(c)) != 0) return function(at, s, i);
        std::size_t j = i;
        while (j < s.size() && (std::isdigit(static_cast<unsigned char>(s[j])) != 0 || s[j] == '.'))
            ++j;
        double v = 0;
        const auto [end, ec] = std::from_chars(s.data() + i, s.data() + j, v);
        if (j == i || ec != std::errc() || end != s.data() + j)
            throw fail(at, "bad number '" + s.substr(i, std::max<std::size_t>(1, j - i)) + "'");
        i = j;
        return v;
    }

    // '#' and what names the parameter: a number, a value ('#[...]', '##1'), or '<name>'.
    struct ParameterName {
        std::optional<int> number;
        std::string name;  // normalised, for #<name>
    };
    ParameterName parameter_name(std::size_t at, const std::string& s, std::size_t& i) {
        ++i;  // '#'
        skip_blanks(s, i);
        ParameterName p;
        if (i < s.size() && s[i] == '<') {
            const auto close = s.find('>', i);
            if (close == std::string::npos) throw fail(at, "a named parameter lacks its '>'");
            p.name = normal_name(s.substr(i + 1, close - i - 1));
            if (p.name.empty()) throw fail(at, "an empty parameter name");
            i = close + 1;
            return p;
        }
        const double v = value(at, s, i);
        const double whole = std::round(v);
        if (std::abs(v - whole) > 1e-4 || whole < 1 || whole > 5602)
            throw fail(at, "#" + plain_number(v) + " is no parameter (LinuxCNC's run 1 to 5602)");
        p.number = static_cast<int>(whole);
        return p;
    }

    double parameter_value(std::size_t at, const std::string& s, std::size_t& i) {
        const auto p = parameter_name(at, s, i);
        if (p.number) {
            if (*p.number >= kFirstSystemParameter)
                throw fail(at, "#" + std::to_string(*p.number) +
                                   " is the controller's own (its offsets, tool table or "
                                   "position): its value is not in the file");
            if (*p.number <= kLocalParameters)
                return frames_.back().numbered[static_cast<std::size_t>(*p.number)];
            const auto found = numbered_.find(*p.number);
            return found == numbered_.end() ? 0.0 : found->second;
        }
        if (p.name.front() == '_') {
            const auto found = globals_.find(p.name);
            if (found != globals_.end()) return found->second;
        } else {
            const auto& named = frames_.back().named;
            const auto found = named.find(p.name);
            if (found != named.end()) return found->second;
        }
        throw fail(at, "named parameter #<" + p.name + "> is read before it is set");
    }

    bool exists(const ParameterName& p) const {
        if (p.number) return true;
        if (p.name.front() == '_') return globals_.count(p.name) != 0;
        return frames_.back().named.count(p.name) != 0;
    }

    double function(std::size_t at, const std::string& s, std::size_t& i) {
        std::size_t j = i;
        while (j < s.size() && (std::isalpha(static_cast<unsigned char>(s[j])) != 0)) ++j;
        std::string name = s.substr(i, j - i);
        for (auto& ch : name) ch = upper(ch);
        i = j;
        skip_blanks(s, i);
        if (i >= s.size() || s[i] != '[')
            throw fail(at, "'" + name + "' is no function of LinuxCNC's (or lacks its '[')");
        if (name == "EXISTS") {
            ++i;
            skip_blanks(s, i);
            if (i >= s.size() || s[i] != '#') throw fail(at, "EXISTS takes a parameter");
            const bool is = exists(parameter_name(at, s, i));
            skip_blanks(s, i);
            if (i >= s.size() || s[i] != ']') throw fail(at, "EXISTS lacks its ']'");
            ++i;
            return is ? 1 : 0;
        }
        const double a = value(at, s, i);
        const double to_rad = std::numbers::pi / 180;
        if (name == "ATAN") {
            skip_blanks(s, i);
            if (i >= s.size() || s[i] != '/') throw fail(at, "ATAN takes [y]/[x]");
            ++i;
            const double b = value(at, s, i);
            return std::atan2(a, b) / to_rad;
        }
        const auto domain = [&](bool ok) {
            if (!ok) throw fail(at, name + " of " + plain_number(a) + " is undefined");
        };
        if (name == "ABS") return std::abs(a);
        if (name == "ACOS") return domain(a >= -1 && a <= 1), std::acos(a) / to_rad;
        if (name == "ASIN") return domain(a >= -1 && a <= 1), std::asin(a) / to_rad;
        if (name == "COS") return std::cos(a * to_rad);
        if (name == "SIN") return std::sin(a * to_rad);
        if (name == "TAN") return std::tan(a * to_rad);
        if (name == "EXP") return std::exp(a);
        if (name == "LN") return domain(a > 0), std::log(a);
        if (name == "SQRT") return domain(a >= 0), std::sqrt(a);
        if (name == "FIX") return std::floor(a);
        if (name == "FUP") return std::ceil(a);
        if (name == "ROUND") return std::round(a);
        throw fail(at, "'" + name + "' is no function of LinuxCNC's");
    }

    // Binary operators, LinuxCNC's precedence: ** ; * / MOD ; + - ; comparisons ; AND OR XOR.
    static int precedence(const std::string& op) {
        if (op == "**") return 5;
        if (op == "*" || op == "/" || op == "MOD") return 4;
        if (op == "+" || op == "-") return 3;
        if (op == "EQ" || op == "NE" || op == "GT" || op == "GE" || op == "LT" || op == "LE")
            return 2;
        return 1;  // AND OR XOR
    }

    std::optional<std::string> operator_at(const std::string& s, std::size_t i) const {
        if (i >= s.size()) return std::nullopt;
        if (s.compare(i, 2, "**") == 0) return "**";
        if (s[i] == '*' || s[i] == '/' || s[i] == '+' || s[i] == '-') return std::string(1, s[i]);
        for (const char* op : {"MOD", "AND", "XOR", "EQ", "NE", "GT", "GE", "LT", "LE", "OR"}) {
            const std::size_t n = std::char_traits<char>::length(op);
            if (i + n > s.size()) continue;
            bool same = true;
            for (std::size_t k = 0; k < n; ++k) same = same && upper(s[i + k]) == op[k];
            if (same) return std::string(op);
        }
        return std::nullopt;
    }

    double apply(std::size_t at, const std::string& op, double a, double b) const {
        if (op == "**") {
            const double r = std::pow(a, b);
            if (!std::isfinite(r))
                throw fail(at, plain_number(a) + " ** " + plain_number(b) + " is undefined");
            return r;
        }
        if (op == "*") return a * b;
        if (op == "/" || op == "MOD") {
            if (b == 0) throw fail(at, "division by zero in an expression");
            if (op == "/") return a / b;
            const double r = std::fmod(a, b);
            return r < 0 ? r + std::abs(b) : r;  // LinuxCNC's MOD is never negative
        }
        if (op == "+") return a + b;
        if (op == "-") return a - b;
        if (op == "EQ") return a == b ? 1 : 0;
        if (op == "NE") return a != b ? 1 : 0;
        if (op == "GT") return a > b ? 1 : 0;
        if (op == "GE") return a >= b ? 1 : 0;
        if (op == "LT") return a < b ? 1 : 0;
        if (op == "LE") return a <= b ? 1 : 0;
        if (op == "AND") return (a != 0 && b != 0) ? 1 : 0;
        if (op == "OR") return (a != 0 || b != 0) ? 1 : 0;
        return ((a != 0) != (b != 0)) ? 1 : 0;  // XOR
    }

    // Inside '[ ]': values and binary operators, reduced by precedence, left to right.
    double expression(std::size_t at, const std::string& s, std::size_t& i) {
        std::vector<double> values{value(at, s, i)};
        std::vector<std::string> ops;
        while (true) {
            skip_blanks(s, i);
            if (i < s.size() && s[i] == ']') break;
            const auto op = operator_at(s, i);
            if (!op) {
                if (i >= s.size()) throw fail(at, "an expression lacks its ']'");
                throw fail(at, "unexpected '" + s.substr(i, 1) + "' in an expression");
            }
            i += op->size();
            while (!ops.empty() && precedence(ops.back()) >= precedence(*op)) {
                const double b = values.back();
                values.pop_back();
                values.back() = apply(at, ops.back(), values.back(), b);
                ops.pop_back();
            }
            ops.push_back(*op);
            values.push_back(value(at, s, i));
        }
        while (!ops.empty()) {
            const double b = values.back();
            values.pop_back();
            values.back() = apply(at, ops.back(), values.back(), b);
            ops.pop_back();
        }
        return values.front();
    }

    // --- lines -----------------------------------------------------------------------------

    void set_parameter(std::size_t at, const ParameterName& p, double v) {
        if (p.number) {
            if (*p.number >= kFirstSystemParameter)
                throw fail(at, "#" + std::to_string(*p.number) +
                                   " is the controller's own (its offsets, tool table or "
                                   "position): a job that sets it is not compensated");
            if (*p.number <= kLocalParameters)
                frames_.back().numbered[static_cast<std::size_t>(*p.number)] = v;
            else
                numbered_[*p.number] = v;
        } else if (p.name.front() == '_') {
            globals_[p.name] = v;
        } else {
            frames_.back().named[p.name] = v;
        }
    }

    // The line with every value evaluated; assignments take effect after the line is read, as
    // in LinuxCNC. A line with nothing to evaluate is passed on as written.
    std::string evaluated(std::size_t at) {
        const std::string& code = split_[at].code;
        if (code.find_first_of("#[") == std::string::npos) return raw_[at];
        std::string words;
        std::vector<std::pair<ParameterName, double>> settings;
        std::size_t i = 0;
        while (true) {
            skip_blanks(code, i);
            if (i >= code.size()) break;
            const char c = code[i];
            if (c == '#') {
                auto p = parameter_name(at, code, i);
                skip_blanks(code, i);
                if (i >= code.size() || code[i] != '=')
                    throw fail(at, "a parameter at the start of a word must be set with '='");
                ++i;
                settings.emplace_back(std::move(p), value(at, code, i));
                continue;
            }
            if (c == '/' && words.empty()) {
                words += '/';
                ++i;
                continue;
            }
            if (std::isalpha(static_cast<unsigned char>(c)) == 0 && c != '@' && c != '^')
                throw fail(at, std::string("unexpected character '") + c + "'");
            ++i;
            const double v = value(at, code, i);
            if (!words.empty() && words != "/") words += ' ';
            words += upper(c);
            words += plain_number(v);
        }
        for (const auto& [p, v] : settings) set_parameter(at, p, v);
        const std::string& comment = split_[at].comment;
        if (words.empty()) return comment;
        return comment.empty() ? words : words + " " + comment;
    }

    bool ends_program(std::size_t at) const {
        // M2 and M30 end the program; LinuxCNC reads no further.
        const std::string& code = split_[at].code;
        for (std::size_t i = 0; i + 1 < code.size(); ++i) {
            if (upper(code[i]) != 'M') continue;
            std::size_t j = i + 1;
            while (j < code.size() && is_blank(code[j])) ++j;
            std::size_t k = j;
            while (k < code.size() && std::isdigit(static_cast<unsigned char>(code[k])) != 0) ++k;
            if (k == j || (k < code.size() && code[k] == '.')) continue;
            int number = 0;
            std::from_chars(code.data() + j, code.data() + k, number);
            if (number == 2 || number == 30) return true;
        }
        return false;
    }

    const ProgramLimits& limits_;
    std::vector<std::string> raw_;
    std::vector<SplitLine> split_;
    std::vector<std::optional<OWord>> o_words_;
    std::map<std::string, std::size_t> subs_;
    std::vector<Frame> frames_;
    std::vector<Loop> loops_;
    std::vector<std::size_t> loop_frames_;  // the call depth each loop runs in
    std::map<int, double> numbered_;
    std::map<std::string, double> globals_;
    std::vector<ExecutedLine> out_;
};

}  // namespace

bool uses_ngc_language(std::string_view job) {
    long number = 0;
    for (const std::string_view raw : lines_of_job(job)) {
        try {
            const auto line = split_comments(raw, ++number);
            if (line.code.find_first_of("#[") != std::string::npos || o_word_of(line.code))
                return true;
        } catch (const ProgramError&) {
            return false;  // an unclosed comment: the plain reader names it
        }
    }
    return false;
}

std::vector<ExecutedLine> run_ngc_program(std::string_view job, const ProgramLimits& limits) {
    return Machine(job, limits).run();
}

}  // namespace calbox::gcode
