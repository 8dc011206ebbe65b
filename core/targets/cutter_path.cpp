#include "core/targets/cutter_path.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string_view>

#include "core/targets/compensate.hpp"

namespace calbox::targets {
namespace {

using geometry::Point2;
using job_words::Code;
using job_words::command_words;
using job_words::CommandWords;
using job_words::has_m;
using job_words::is_cycle;
using job_words::kOtherAxes;
using job_words::number;
using job_words::ReadLine;
using job_words::trailing_comment;

class CutterPath {
  public:
    using Lines = JobLines;
    using Read = ReadJobLine;

    CutterPath(std::optional<double> tool_radius_mm, Read read)
        : tool_radius_mm_(tool_radius_mm), read_(std::move(read)) {}

    Lines run(const Lines& in) {
        for (const auto& [raw, number] : in) {
            number_ = number;
            ReadLine r;
            try {
                r = read_(raw, number);
            } catch (const gcode::SyntaxError&) {
                pass(raw);  // refused where the compensator reads it, naming the column
                continue;
            }
            line(raw, r);
        }
        if (side_ != 0) {
            refuse_gouge(cutter_, kRunsBackwards);
            flush();
        }
        return std::move(out_);
    }

  private:
    // A move held until the next one says where it ends (an inside corner pulls it back).
    struct Held {
        bool move = false;   // a move at the held end (else a line written as it is)
        std::string head;    // a move's words that act before its motion
        std::string motion;  // "G0" or "G1"
        std::string tail;    // its Z word, its stops and comments
        std::string raw;     // a line as written
        std::string n;       // its line number word, written first
        long number = 0;
        // The way the move goes, as LinuxCNC queues it: the programmed move's direction (none
        // for a height change), the cutter's for the entry move.
        Point2 along{};
    };

    CompensateError fail(const std::string& why) const {
        return CompensateError("line " + std::to_string(number_) + ": " + why);
    }
    void pass(const std::string& raw) {
        if (side_ != 0 && started_) {
            Held h;
            h.raw = raw;
            h.number = number_;
            held_.push_back(std::move(h));
        } else
            out_.emplace_back(raw, number_);
    }
    static std::string xy(Point2 p) { return " X" + number(p.x, 6) + " Y" + number(p.y, 6); }

    void line(const std::string& raw, const ReadLine& r) {
        const gcode::Line& l = r.line;
        const auto has_code = [&](int n, int sub) {
            return std::any_of(r.codes.begin(), r.codes.end(),
                               [&](Code c) { return c.number == n && c.subcode == sub; });
        };
        const int turn_on = has_code(41, -1) || has_code(41, 1)   ? 1
                            : has_code(42, -1) || has_code(42, 1) ? -1
                                                                  : 0;
        const bool turn_off = has_code(40, -1);
        if (turn_on != 0 && side_ != 0)
            throw fail(
                "cutter radius compensation turned on where it is on already: LinuxCNC refuses "
                "it too");
        // The frame and modes, read before the line's move as the controller reads them.
        for (const Code c : r.codes) {
            if (c.is(90)) absolute_ = true;
            if (c.is(91)) absolute_ = false;
            if (c.is(20) || c.is(21)) {
                const double unit = c.is(20) ? 25.4 : 1.0;
                if (unit != unit_mm_ && at_)
                    at_ = Point2{at_->x * unit_mm_ / unit, at_->y * unit_mm_ / unit};
                unit_mm_ = unit;
            }
            if (c.is(17) || c.is(18) || c.is(19)) plane_ = c.number;
            if (c.is_motion()) motion_ = c.number;
            if (c.is(80)) motion_ = -1;
            if (c.subcode < 0 && is_cycle(c.number)) motion_ = c.number;
        }
        const bool reframes = std::any_of(r.codes.begin(), r.codes.end(), [](Code c) {
            return c.is(10) || c.is(28) || c.is(30) || c.is(52) || c.is(53) || c.number == 92 ||
                   (c.number >= 54 && c.number <= 59);
        });
        if (turn_on != 0) {
            if (plane_ != 17)
                throw fail("cutter radius compensation outside the XY plane (G18, G19)");
            const bool diameter_given = has_code(41, 1) || has_code(42, 1);
            double radius = 0;
            if (diameter_given) {
                const auto d = l.value('D');
                if (!d || *d < 0)
                    throw fail("G41.1 / G42.1 without the cutter's diameter (D, 0 or more)");
                if (l.has('L'))
                    throw fail("G41.1 / G42.1 with a lathe tool's orientation (L): a lathe job");
                radius = *d / 2;
            } else {
                if (!tool_radius_mm_)
                    throw fail(
                        "cutter radius compensation (G41 / G42) by the controller's tool table: "
                        "give the cutter's radius (calbox compensate --tool-radius MM), or have "
                        "the CAM write the compensated path");
                radius = *tool_radius_mm_ / unit_mm_;
            }
            side_ = turn_on;
            radius_ = radius;
            started_ = false;
        }
        const bool axes = l.has('X') || l.has('Y');
        const bool moves = motion_ >= 0 && motion_ <= 3 && (axes || l.has('Z'));
        if (side_ == 0 || radius_ == 0) {
            // Off, or a radius of 0 (LinuxCNC moves on the path itself): the line as it is, its
            // compensation words taken out; the place it ends at followed.
            const bool was_on = side_ != 0;
            if (turn_off) {
                if (was_on) flush();
                side_ = 0;
            }
            follow(l, r, reframes, axes);
            out_.emplace_back(turn_on != 0 ? without_compensation_words(raw, r) : raw, number_);
            return;
        }
        if (turn_off) {
            // LinuxCNC goes on from where the cutter is.
            refuse_gouge(cutter_, kRunsBackwards);
            flush();
            side_ = 0;
            at_ = cutter_;
            programmed_ = cutter_;
            follow(l, r, reframes, axes);
            out_.emplace_back(raw, number_);
            return;
        }
        // LinuxCNC ends the held moves at a program's end as at G40.
        if (started_ && (has_m(l, 2) || has_m(l, 30))) refuse_gouge(cutter_, kRunsBackwards);
        // On: what this carries through.
        if (std::any_of(r.codes.begin(), r.codes.end(),
                        [](Code c) { return c.is(20) || c.is(21); }))
            throw fail(
                "a change of units under cutter radius compensation: LinuxCNC refuses it too");
        if (r.polar) throw fail(refusal("polar words"));
        if (reframes) throw fail(refusal("an offset, a machine-coordinate move or a return home"));
        if (!absolute_) throw fail(refusal("incremental distances (G91)"));
        if (plane_ != 17) throw fail(refusal("another plane than XY (G18, G19)"));
        if (motion_ == 2 || motion_ == 3)
            if (moves || l.has('I') || l.has('J') || l.has('R')) throw fail(refusal("an arc"));
        if (motion_ > 3 && (axes || l.has('R'))) throw fail(refusal("a canned cycle"));
        if (l.is('M', 6) ||
            std::any_of(l.parameters.begin(), l.parameters.end(),
                        [](const auto& w) { return w.letter == 'M' && w.value && *w.value == 6; }))
            throw fail(
                "a tool change under cutter radius compensation: LinuxCNC refuses it too (turn it "
                "off with G40 first)");
        for (const auto& w : l.parameters)
            if (kOtherAxes.find(w.letter) != std::string_view::npos)
                throw fail(refusal(std::string("a move of axis ") + w.letter));
        if (!moves || !axes) {
            if (moves && !started_)
                throw fail(
                    "the first move under cutter radius compensation has no X or Y: LinuxCNC "
                    "refuses it too (\"Length of cutter compensation entry move is not greater "
                    "than the tool radius\")");
            pass(turn_on != 0 ? without_compensation_words(raw, r) : raw);
            return;
        }
        if (!at_)
            throw fail(
                "cutter radius compensation starts where the position is not known (no move "
                "has given both X and Y since the start or since an offset or a return home)");
        const Point2 to{l.value('X').value_or(programmed_.x), l.value('Y').value_or(programmed_.y)};
        Held move = block(l, r, raw);
        if (!started_)
            entry(to, move);
        else
            next(to, move);
    }

    static std::string refusal(const std::string& what) {
        return what +
               " under cutter radius compensation: calbox carries it through straight moves in "
               "the XY plane (G17) in absolute distances (G90); have the CAM write the "
               "compensated path";
    }

    // The line split for a move under compensation: what acts before its motion (its other G
    // codes, F, S, T, M words that are not stops), its motion, what follows (Z, stops, comments).
    Held block(const gcode::Line& l, const ReadLine& r, const std::string& raw) const {
        Held h;
        h.move = true;
        h.number = number_;
        if (l.line_number) h.n = "N" + std::to_string(*l.line_number) + " ";
        for (const Code c : r.codes) {
            if (c.is_motion() || c.number == 40 || c.number == 41 || c.number == 42) continue;
            if (!h.head.empty()) h.head += ' ';
            h.head += c.text();
        }
        const bool turns_on = std::any_of(r.codes.begin(), r.codes.end(),
                                          [](Code c) { return c.number == 41 || c.number == 42; });
        for (const auto& w : l.parameters) {
            if (std::string_view("GMXYZN").find(w.letter) != std::string_view::npos) continue;
            if (w.letter == 'D' && turns_on) continue;  // the compensation's, taken out
            if (std::string_view("FST").find(w.letter) == std::string_view::npos)
                throw fail(refusal(std::string("a move with ") + w.letter));
            if (!h.head.empty()) h.head += ' ';
            h.head += w.letter;
            if (w.value) h.head += number(*w.value, 6);
        }
        const CommandWords m = command_words(l);
        h.head += m.before;
        while (!h.head.empty() && h.head.front() == ' ') h.head.erase(0, 1);
        h.motion = motion_ == 0 ? "G0" : "G1";
        if (const auto z = l.value('Z')) h.tail = " Z" + number(*z, 6);
        h.tail += m.after + trailing_comment(raw);
        return h;
    }

    // The entry move: its end a radius off the programmed end, square to the move.
    void entry(Point2 to, Held move) {
        const Point2 from = programmed_;
        const double distance = std::hypot(to.x - from.x, to.y - from.y);
        if (!(distance > radius_))
            throw fail("the first move under cutter radius compensation is " + number(distance, 4) +
                       " long, not longer than the cutter's radius " + number(radius_, 4) +
                       ": LinuxCNC refuses it too (\"Length of cutter compensation entry move "
                       "is not greater than the tool radius\")");
        const double along = std::atan2(to.y - from.y, to.x - from.x);
        const double normal = along + (side_ > 0 ? kHalfPi : -kHalfPi);
        from_ = from;
        cutter_ = {to.x + radius_ * std::cos(normal), to.y + radius_ * std::sin(normal)};
        move.along = {cutter_.x - from.x, cutter_.y - from.y};
        held_.push_back(std::move(move));
        programmed_ = to;
        started_ = true;
    }

    // A later move: the corner at the programmed point it starts from, then the move offset.
    void next(Point2 to, Held move) {
        const Point2 corner = programmed_;
        if (to.x == corner.x && to.y == corner.y) {  // no XY motion: a height change held
            held_.push_back(std::move(move));
            return;
        }
        // LinuxCNC's angles: theta from the programmed corner to where the cutter is, alpha
        // along the new move; beta the turn, -90 degrees for a square inside corner.
        double theta = std::atan2(cutter_.y - corner.y, cutter_.x - corner.x);
        double alpha = std::atan2(to.y - corner.y, to.x - corner.x);
        double beta = 0, gamma = 0;
        if (side_ > 0) {
            if (theta < alpha) theta += 2 * std::numbers::pi;
            beta = theta - alpha - kHalfPi;
            gamma = kHalfPi;
        } else {
            if (alpha < theta) alpha += 2 * std::numbers::pi;
            beta = alpha - theta - kHalfPi;
            gamma = -kHalfPi;
        }
        const Point2 end{to.x + radius_ * std::cos(alpha + gamma),
                         to.y + radius_ * std::sin(alpha + gamma)};
        const Point2 start{corner.x + radius_ * std::cos(alpha + gamma),
                           corner.y + radius_ * std::sin(alpha + gamma)};
        const bool concave = beta < -kConcaveCorner || beta > std::numbers::pi + kConcaveCorner;
        std::string corner_move;
        if (concave) {
            const double half_corner = (beta + std::numbers::pi) / 2;
            if (half_corner == 0)
                throw fail(
                    "a zero-degree inside corner under cutter radius compensation: "
                    "LinuxCNC refuses it too");
            const double retreat = radius_ / std::tan(half_corner);
            pull_back({cutter_.x + retreat * std::cos(theta + gamma),
                       cutter_.y + retreat * std::sin(theta + gamma)});
        } else if (beta > kConcaveCorner) {
            // Around the programmed corner: an arc for a feed, a traverse across for G0. LinuxCNC
            // ends the held moves where the cutter is first, checking them as at an inside one.
            refuse_gouge(cutter_, kRunsBackwards);
            if (move.motion == "G1") {
                corner_move = (side_ > 0 ? "G2" : "G3") + xy(start) + " I" +
                              number(corner.x - cutter_.x, 6) + " J" +
                              number(corner.y - cutter_.y, 6);
            } else {
                corner_move = "G0" + xy(start);
            }
        }
        flush();
        move.along = {to.x - corner.x, to.y - corner.y};
        if (!corner_move.empty()) {
            from_ = start;  // the move starts after its corner's
            // The block's words that act before its motion act before the corner too.
            out_.emplace_back(move.n + join(corner_move, move.head), move.number);
            move.head.clear();
            move.n.clear();
        }
        held_.push_back(std::move(move));
        cutter_ = end;
        programmed_ = to;
    }

    // An inside corner: every move held ends at `p` instead (LinuxCNC's move_endpoint_and_flush);
    // a move that would run backwards to it gouges, and is refused as LinuxCNC refuses it.
    void pull_back(Point2 p) {
        refuse_gouge(p,
                     "an inside corner the cutter cannot reach without gouging the move before it");
        cutter_ = p;
    }

    // LinuxCNC checks every held move against where it now ends, at an inside corner and at G40
    // alike: the move's own direction against the way from where the held moves start to `p`. A
    // move shorter than the inside corner before it takes back runs backwards there.
    void refuse_gouge(Point2 p, const std::string& what) const {
        const Point2 d_now{p.x - from_.x, p.y - from_.y};
        for (const Held& h : held_)
            if (h.move && h.along.x * d_now.x + h.along.y * d_now.y < 0)
                throw fail(what + " (the move on line " + std::to_string(h.number) +
                           "): LinuxCNC refuses it too (a smaller cutter, or a wider corner)");
    }

    void flush() {
        for (auto& h : held_) {
            if (!h.move) {
                out_.emplace_back(std::move(h.raw), h.number);
                continue;
            }
            // The held end is the cutter's, for the move and the height changes after it.
            out_.emplace_back(h.n + join(h.motion + xy(cutter_), h.head) + h.tail, h.number);
        }
        held_.clear();
        from_ = cutter_;
    }

    static std::string join(const std::string& a, const std::string& b) {
        return a.empty() ? b : a + " " + b;
    }

    // The line without G40 / G41 / G42 (and their D, L): what remains of it for the compensator.
    static std::string without_compensation_words(const std::string& raw, const ReadLine& r) {
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
            if (std::string_view("GMND").find(w.letter) != std::string_view::npos) continue;
            add(std::string(1, w.letter) + (w.value ? number(*w.value, 6) : std::string()));
        }
        const CommandWords m = command_words(l);
        text += m.before + m.after + trailing_comment(raw);
        while (!text.empty() && text.front() == ' ') text.erase(0, 1);
        return text;
    }

    // Where the programmed path stands when compensation is off.
    void follow(const gcode::Line& l, const ReadLine& r, bool reframes, bool axes) {
        if (reframes || r.polar) {
            at_.reset();
            programmed_ = {};
            return;
        }
        if (!axes) return;
        if (motion_ >= 0 && motion_ <= 3) {
            if (absolute_) {
                if (at_ || (l.has('X') && l.has('Y')))
                    at_ = Point2{l.value('X').value_or(at_ ? at_->x : 0),
                                 l.value('Y').value_or(at_ ? at_->y : 0)};
            } else if (at_) {
                at_ = Point2{at_->x + l.value('X').value_or(0), at_->y + l.value('Y').value_or(0)};
            }
        } else if (motion_ > 3) {
            at_.reset();  // a canned cycle's holes: not followed here
        }
        if (at_) programmed_ = *at_;
        cutter_ = programmed_;
    }

    static constexpr const char* kRunsBackwards =
        "a move the cutter would run backwards along (shorter than the inside corner before it "
        "takes back)";
    static constexpr double kHalfPi = std::numbers::pi / 2;
    // LinuxCNC's TOLERANCE_CONCAVE_CORNER, radians: a turn this small is no corner.
    static constexpr double kConcaveCorner = 0.05;

    std::optional<double> tool_radius_mm_;
    Read read_;
    Lines out_;
    std::vector<Held> held_;
    long number_ = 0;
    int side_ = 0;  // 1 left (G41), -1 right (G42), 0 off
    double radius_ = 0;
    bool started_ = false;  // the entry move made
    bool absolute_ = true;
    double unit_mm_ = 1;
    int plane_ = 17, motion_ = -1;
    std::optional<Point2> at_;  // the programmed position, where known (off)
    Point2 programmed_, cutter_, from_;
};

}  // namespace

JobLines cutter_path(const JobLines& lines, std::optional<double> tool_radius_mm,
                     const ReadJobLine& read) {
    return CutterPath(tool_radius_mm, read).run(lines);
}

}  // namespace calbox::targets
