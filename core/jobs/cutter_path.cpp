#include "core/jobs/cutter_path.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string_view>

#include "core/jobs/compensate.hpp"
#include "core/jobs/cutter_geometry.hpp"
#include "core/jobs/cutter_rules.hpp"

namespace calbox::jobs {
namespace {

using geometry::distance;
using geometry::Point2;
using job_words::Code;
using job_words::has_m;
using job_words::is_cycle;
using job_words::kOtherAxes;
using job_words::number;
using job_words::ReadLine;

using cutter_geometry::angle_to;
using cutter_geometry::sweep_of;
using cutter_geometry::toward;
using cutter_rules::arc_words_refusal;
using cutter_rules::compensation_turned_on;
using cutter_rules::mode_change_refusal;
using cutter_rules::reframes_position;
using cutter_rules::refusal;
using std::numbers::pi;

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
        // An arc (G2, G3): the cutter's centre and way round (1 counter-clockwise), and its sweep
        // as queued, from where it starts, which LinuxCNC checks a pulled-back end against.
        bool arc = false;
        int turn = 0;
        bool absolute = true;  // G90 on its line (G91: its end written as a step)
        Point2 centre{};
        double sweep_rad = 0;
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
    // Whether the line names a motion (G0 to G3): one alone moves to where the path stands.
    static bool has_motion(const ReadLine& r) {
        return std::any_of(r.codes.begin(), r.codes.end(), [](Code c) { return c.is_motion(); });
    }
    static std::string xy(Point2 p) { return " X" + number(p.x, 6) + " Y" + number(p.y, 6); }
    // An outside corner's arc about the programmed corner, from where the cutter is to `start`.
    std::string corner_arc(Point2 start, Point2 corner) const {
        return (side_ > 0 ? "G2" : "G3") + to_xy(start) + " I" + number(corner.x - cutter_.x, 6) +
               " J" + number(corner.y - cutter_.y, 6);
    }
    // The corner written ahead of the move, which starts at its end; the block's words that act
    // before its motion act before the corner.
    void write_corner(const std::string& corner_move, Point2 start, Held& move) {
        from_ = start;
        out_.emplace_back(move.n + join(corner_move, move.head), move.number);
        move.head.clear();
        move.n.clear();
    }
    // A move from where the cutter is to `p`, in the distance mode in force.
    std::string to_xy(Point2 p) const {
        return absolute_ ? xy(p) : xy({p.x - cutter_.x, p.y - cutter_.y});
    }

    // A line with compensation off: written without its compensation words, the place it ends
    // at followed.
    void write_uncompensated(const std::string& raw, const ReadLine& r, bool reframes,
                             bool turning_on, bool axes) {
        const std::string text = after_off(r.line, r, reframes, raw, turning_on);
        follow(r.line, r, reframes, axes);
        out_.emplace_back(text, number_);
    }

    void line(const std::string& raw, const ReadLine& r) {
        const gcode::Line& l = r.line;
        const auto has_code = [&](int n, int sub) {
            return std::any_of(r.codes.begin(), r.codes.end(),
                               [&](Code c) { return c.number == n && c.subcode == sub; });
        };
        const int turn_on = compensation_turned_on(r);
        const bool turn_off = has_code(40, -1);
        if (turn_on != 0 && side_ != 0)
            throw fail(
                "cutter radius compensation turned on where it is on already: LinuxCNC refuses "
                "it too");
        read_modes(r);
        const bool reframes = reframes_position(r);
        if (turn_on != 0) compensation_on(l, turn_on, has_code(41, 1) || has_code(42, 1));
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
            write_uncompensated(raw, r, reframes, turn_on != 0, axes);
            return;
        }
        if (turn_off) {
            // LinuxCNC's position is the programmed path's end now; the cutter stands off it.
            refuse_gouge(cutter_, kRunsBackwards);
            flush();
            side_ = 0;
            at_ = programmed_;
            left_at_ = cutter_;
            write_uncompensated(raw, r, reframes, false, axes);
            return;
        }
        // LinuxCNC ends the held moves at a program's end as at G40, and reads nothing after it.
        if (started_ && (has_m(l, 2) || has_m(l, 30))) {
            refuse_gouge(cutter_, kRunsBackwards);
            if (!moves) {
                flush();
                side_ = 0;
                out_.emplace_back(raw, number_);
                return;
            }
        }
        refuse_under_compensation(r, reframes, moves, axes);
        move_under_compensation(raw, r, turn_on != 0, moves, axes);
    }

    // Every position kept is in the job's units: a change of units (G20, G21) restates them.
    void change_units(double unit_mm) {
        const double scale = unit_mm_ / unit_mm;
        const auto restate = [scale](Point2 p) { return Point2{p.x * scale, p.y * scale}; };
        if (at_) at_ = restate(*at_);
        if (left_at_) left_at_ = restate(*left_at_);
        programmed_ = restate(programmed_);
        cutter_ = restate(cutter_);
        unit_mm_ = unit_mm;
    }

    // The frame and modes, read before the line's move as the controller reads them.
    void read_modes(const ReadLine& r) {
        for (const Code c : r.codes) {
            if (c.is(90)) absolute_ = true;
            if (c.is(91)) absolute_ = false;
            if (c.is(20) || c.is(21)) change_units(c.is(20) ? 25.4 : 1.0);
            if (c.is(17) || c.is(18) || c.is(19)) plane_ = c.number;
            if (c.is_motion()) motion_ = c.number;
            if (c.is(80)) motion_ = -1;
            if (c.subcode < 0 && is_cycle(c.number)) motion_ = c.number;
        }
    }

    // G41 / G42 (`turn_on` 1 left, -1 right), with its diameter on the line (G41.1 / G42.1) or
    // the tool table's.
    void compensation_on(const gcode::Line& l, int turn_on, bool diameter_given) {
        if (plane_ != 17) throw fail("cutter radius compensation outside the XY plane (G18, G19)");
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
        if (radius_ != 0) left_at_.reset();  // the entry move is written whole
    }

    // What LinuxCNC refuses under compensation, and what calbox does not carry through.
    void refuse_under_compensation(const ReadLine& r, bool reframes, bool moves, bool axes) const {
        const gcode::Line& l = r.line;
        if (const auto why = mode_change_refusal(r); !why.empty()) throw fail(why);
        if (r.polar) throw fail(refusal("polar words"));
        if (reframes) throw fail(refusal("an offset, a machine-coordinate move or a return home"));
        if (plane_ != 17) throw fail(refusal("another plane than XY (G18, G19)"));
        if (const auto why = motion_ == 2 || motion_ == 3 ? arc_words_refusal(l, moves) : "";
            !why.empty())
            throw fail(why);
        if (motion_ > 3 && (axes || l.has('R'))) throw fail(refusal("a canned cycle"));
        if (has_m(l, 6))
            throw fail(
                "a tool change under cutter radius compensation: LinuxCNC refuses it too (turn it "
                "off with G40 first)");
        for (const auto& w : l.parameters)
            if (kOtherAxes.find(w.letter) != std::string_view::npos)
                throw fail(refusal(std::string("a move of axis ") + w.letter));
    }

    // A line under compensation: a move held (its end said by the next), or a line between moves.
    void move_under_compensation(const std::string& raw, const ReadLine& r, bool turns_on,
                                 bool moves, bool axes) {
        const gcode::Line& l = r.line;
        const bool arc = motion_ == 2 || motion_ == 3;
        // A program stop (M0, M1, M60) empties LinuxCNC's queue: the held moves end where they
        // are (checked as at G40), and the next inside corner pulls nothing back.
        const bool stops = has_m(l, 0) || has_m(l, 1) || has_m(l, 60);
        if (!moves || (!axes && !arc)) {
            between_moves(raw, r, turns_on, moves || has_motion(r), stops);
            return;
        }
        if (!at_)
            throw fail(
                "cutter radius compensation starts where the position is not known (no move "
                "has given both X and Y since the start or since an offset or a return home)");
        const Point2 to = absolute_ ? Point2{l.value('X').value_or(programmed_.x),
                                             l.value('Y').value_or(programmed_.y)}
                                    : Point2{programmed_.x + l.value('X').value_or(0),
                                             programmed_.y + l.value('Y').value_or(0)};
        Held move = block(l, r, raw);
        if (arc) {
            const int turn = motion_ == 3 ? 1 : -1;
            if (!started_)
                entry_arc(to, turn, l, std::move(move));
            else
                next_arc(to, turn, l, std::move(move));
        } else if (!started_) {
            entry(to, std::move(move));
        } else {
            next(to, std::move(move));
        }
        if (stops) {
            refuse_gouge(cutter_, kRunsBackwards);
            flush();
        }
    }

    // A line under compensation that moves no axis of the XY plane (`motion`: it moves, or
    // gives a motion mode alone): passed on, the held moves ended first at a program stop.
    void between_moves(const std::string& raw, const ReadLine& r, bool turns_on, bool motion,
                       bool stops) {
        if (stops && started_) {
            refuse_gouge(cutter_, kRunsBackwards);
            flush();
            out_.emplace_back(raw, number_);
            return;
        }
        if (motion && !started_)
            throw fail(
                "the first move under cutter radius compensation has no X or Y: LinuxCNC "
                "refuses it too (\"Length of cutter compensation entry move is not greater "
                "than the tool radius\")");
        pass(turns_on ? job_words::rebuilt_line(raw, r) : raw);
    }

    // The line split for a move under compensation: what acts before its motion, its motion,
    // what follows (job_words::move_words); the compensation's D and an arc's centre, radius and
    // turn taken out (the cutter's arc is written with its own).
    Held block(const gcode::Line& l, const ReadLine& r, const std::string& raw) const {
        Held h;
        h.move = true;
        h.absolute = absolute_;
        h.number = number_;
        if (l.line_number) h.n = "N" + std::to_string(*l.line_number) + " ";
        const bool turns_on = std::any_of(r.codes.begin(), r.codes.end(),
                                          [](Code c) { return c.number == 41 || c.number == 42; });
        const bool arc = motion_ == 2 || motion_ == 3;
        const std::string taken_out = std::string(turns_on ? "D" : "") + (arc ? "IJRP" : "");
        const job_words::MoveWords words = job_words::move_words(raw, r, taken_out);
        if (words.other != '\0') throw fail(refusal(std::string("a move with ") + words.other));
        h.head = words.head;
        h.tail = words.tail;
        h.motion = motion_ == 0 ? "G0" : "G1";
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
        double theta = angle_to(corner, cutter_);
        double alpha = angle_to(corner, to);
        double beta = 0, gamma = 0;
        if (side_ > 0) {
            if (theta < alpha) theta += 2 * pi;
            beta = theta - alpha - kHalfPi;
            gamma = kHalfPi;
        } else {
            if (alpha < theta) alpha += 2 * pi;
            beta = alpha - theta - kHalfPi;
            gamma = -kHalfPi;
        }
        const Point2 end = toward(to, radius_, alpha + gamma);
        const Point2 start = toward(corner, radius_, alpha + gamma);
        const Held* before = held_move();
        const bool after_arc = before != nullptr && before->arc;
        // LinuxCNC takes a near reversal after an arc the cutter is outside of (an "h" drawn
        // right to left) as an inside corner: the cutter stays above the arc.
        const bool concave = beta < -kConcaveCorner || beta > pi + kConcaveCorner ||
                             (beta > pi - kConcaveCorner && after_arc && before->turn == -side_);
        std::string corner_move;
        if (concave && after_arc) {
            pull_back(arc_meets_line(*before, corner, to));
        } else if (concave) {
            const double half_corner = (beta + pi) / 2;
            if (half_corner == 0)
                throw fail(
                    "a zero-degree inside corner under cutter radius compensation: "
                    "LinuxCNC refuses it too");
            const double retreat = radius_ / std::tan(half_corner);
            pull_back(toward(cutter_, retreat, theta + gamma));
        } else if (beta > kConcaveCorner) {
            // Around the programmed corner: an arc for a feed, a traverse across for G0. LinuxCNC
            // ends the held moves where the cutter is first, checking them as at an inside one.
            refuse_gouge(cutter_, kRunsBackwards);
            corner_move = move.motion == "G1" ? corner_arc(start, corner) : "G0" + to_xy(start);
        }
        flush();
        move.along = {to.x - corner.x, to.y - corner.y};
        if (!concave) from_known_ = true;  // a corner's end, or a tangent join
        if (!corner_move.empty()) write_corner(corner_move, start, move);
        held_.push_back(std::move(move));
        cutter_ = end;
        programmed_ = to;
    }

    // The cutter inside the arc: left of a counter-clockwise one, right of a clockwise one.
    bool inside(int turn) const { return side_ == turn; }

    // The programmed arc's centre from `start`, as LinuxCNC's interpreter finds it (I J from the
    // start; or R, the short way for R > 0), refused where LinuxCNC refuses the arc.
    Point2 arc_centre(Point2 start, Point2 end, int turn, const gcode::Line& l) const {
        const auto found = cutter_geometry::programmed_arc_centre(
            start, end, turn, l.value('I'), l.value('J'), l.value('R'), l.has('K'), unit_mm_);
        if (!found.refused.empty()) throw fail(found.refused + ": LinuxCNC refuses it too");
        return found.centre;
    }

    CompensateError too_tight() const {
        return fail(
            "an arc no larger than the cutter's radius with the cutter inside it: LinuxCNC "
            "refuses it too (a smaller cutter)");
    }

    // The entry move as an arc: the cutter's arc runs from where the cutter is to a radius off
    // the programmed end, about a centre on the line from there to the programmed centre.
    void entry_arc(Point2 to, int turn, const gcode::Line& l, Held move) {
        const Point2 from = programmed_;
        if (!(distance(from, to) > radius_))
            throw fail("the first move under cutter radius compensation, an arc, ends " +
                       number(distance(from, to), 4) +
                       " from where it starts, not farther than the cutter's radius " +
                       number(radius_, 4) +
                       ": LinuxCNC refuses it too (\"Radius of cutter compensation entry arc is "
                       "not greater than the tool radius\")");
        const Point2 centre = arc_centre(from, to, turn, l);
        if (inside(turn) && distance(centre, from) <= radius_) throw too_tight();
        const double out = inside(turn) ? angle_to(to, centre) : angle_to(centre, to);
        const Point2 end = toward(to, radius_, out);
        const auto cutter_centre = cutter_geometry::entry_arc_centre(from, end, centre);
        if (!cutter_centre) throw too_tight();
        move.arc = true;
        move.turn = turn;
        move.centre = *cutter_centre;
        from_ = from;
        from_known_ = false;
        held_.push_back(std::move(move));
        cutter_ = end;
        programmed_ = to;
        started_ = true;
    }

    // A later arc: the corner at the programmed point it starts from (an inside one pulls the
    // held move back to where the two offset paths cross, an outside one is rounded about the
    // programmed corner), then the arc a radius off the programmed one about the same centre.
    void next_arc(Point2 to, int turn, const gcode::Line& l, Held move) {
        const Point2 corner = programmed_;
        const Point2 centre = arc_centre(corner, to, turn, l);
        const double arc_radius = distance(centre, to);
        // LinuxCNC's angles: theta along the move before, alpha along the arc's start; beta the
        // turn between them, from -90 to 270 degrees.
        const double theta = angle_to(corner, cutter_) + (side_ > 0 ? -kHalfPi : kHalfPi);
        double delta = angle_to(corner, centre);
        const double alpha = turn > 0 ? delta - kHalfPi : delta + kHalfPi;
        double beta = side_ > 0 ? theta - alpha : alpha - theta;
        if (beta > 1.5 * pi)
            beta -= 2 * pi;
        else if (beta < -kHalfPi)
            beta += 2 * pi;
        double out = 0;
        if (inside(turn)) {
            if (arc_radius <= radius_) throw too_tight();
            out = angle_to(to, centre);
        } else {
            out = angle_to(centre, to);
            delta += pi;
        }
        const Point2 end = toward(to, radius_, out);
        // A tangent join where the cutter is outside the arc is an inside corner too (the top
        // of an "m").
        const bool concave = beta < -kConcaveCorner || beta > pi + kConcaveCorner ||
                             (std::abs(beta - pi) < kConcaveCorner && !inside(turn));
        move.arc = true;
        move.turn = turn;
        move.centre = centre;
        if (concave) {
            const Held* before = held_move();
            pull_back(before != nullptr && before->arc
                          ? arc_meets_arc(*before, centre, arc_radius, turn)
                          : line_meets_arc(theta, beta, centre, arc_radius, turn));
            flush();
        } else if (beta > kConcaveCorner) {
            // Around the programmed corner by an arc, the held moves ended unchecked.
            const Point2 start = toward(corner, radius_, delta);
            flush();
            write_corner(corner_arc(start, corner), start, move);
        } else {
            flush();  // tangent: the arc goes on from where the cutter is
        }
        if (!concave) from_known_ = true;  // a corner's end, or a tangent join
        move.sweep_rad = sweep_of(from_, centre, turn, end);
        held_.push_back(std::move(move));
        cutter_ = end;
        programmed_ = to;
    }

    CompensateError unreachable(const std::string& what) const {
        return fail(what +
                    " makes an inside corner the cutter cannot reach without gouging: LinuxCNC "
                    "refuses it too (a smaller cutter, or a wider corner)");
    }

    Point2 line_meets_arc(double theta, double beta, Point2 centre, double arc_radius,
                          int turn) const {
        const auto p = cutter_geometry::line_meets_arc(theta, beta, centre, arc_radius, turn,
                                                       inside(turn), radius_);
        if (!p) throw unreachable("a move into an arc");
        return *p;
    }
    Point2 arc_meets_arc(const Held& before, Point2 centre, double arc_radius, int turn) const {
        const double held_radius = distance(before.centre, cutter_);
        if (held_radius == 0 || distance(before.centre, centre) == 0)
            throw fail(
                "two arcs about one centre meet in an inside corner: LinuxCNC refuses it too "
                "(\"Arc to arc motion is invalid because the arcs have the same center\")");
        const auto p = cutter_geometry::arc_meets_arc(
            before.centre, held_radius, inside(before.turn), centre,
            inside(turn) ? arc_radius - radius_ : arc_radius + radius_, turn);
        if (!p) throw unreachable("an arc into an arc");
        return *p;
    }
    Point2 arc_meets_line(const Held& before, Point2 corner, Point2 to) const {
        const auto p =
            cutter_geometry::arc_meets_line(before.centre, distance(before.centre, cutter_),
                                            before.turn, inside(before.turn), corner, to, radius_);
        if (!p) throw unreachable("an arc into a move");
        return *p;
    }

    // An inside corner: every move held ends at `p` instead (LinuxCNC's move_endpoint_and_flush);
    // a move that would run backwards to it gouges, and is refused as LinuxCNC refuses it.
    void pull_back(Point2 p) {
        if (held_move() == nullptr)
            return;  // emptied by a stop: the cutter goes on from where it is
        refuse_gouge(p,
                     "an inside corner the cutter cannot reach without gouging the move before it");
        cutter_ = p;
    }

    // LinuxCNC checks every held move against where it now ends, at an inside corner and at G40
    // alike: the move's own direction against the way from where the held moves start to `p`. A
    // move shorter than the inside corner before it takes back runs backwards there.
    // An arc is checked by its sweep: pulled back past its start, it would go round the other way.
    // After an entry arc LinuxCNC holds no start to check against, and checks nothing.
    void refuse_gouge(Point2 p, const std::string& what) const {
        if (!from_known_) return;
        const Point2 d_now{p.x - from_.x, p.y - from_.y};
        for (const Held& h : held_) {
            if (!h.move) continue;
            const bool backwards =
                h.arc ? h.sweep_rad != 0 && std::abs(sweep_of(from_, h.centre, h.turn, p)) >
                                                std::abs(h.sweep_rad) + 0.001
                      : h.along.x * d_now.x + h.along.y * d_now.y < 0;
            if (backwards)
                throw fail(what + " (the " + (h.arc ? "arc" : "move") + " on line " +
                           std::to_string(h.number) +
                           "): LinuxCNC refuses it too (a smaller cutter, or a wider corner)");
        }
    }

    void flush() {
        // LinuxCNC knows where the held moves start again once it has ended one.
        if (held_move() != nullptr) from_known_ = true;
        Point2 start = from_;
        for (auto& h : held_) {
            if (!h.move) {
                out_.emplace_back(std::move(h.raw), h.number);
                continue;
            }
            // The held end is the cutter's, for the move and the height changes after it; an
            // arc's centre is written from where it starts.
            // G91: the end written as the step from the start.
            const std::string end =
                h.absolute ? xy(cutter_) : xy({cutter_.x - start.x, cutter_.y - start.y});
            std::string motion = h.motion + end;
            if (h.arc)
                motion = (h.turn > 0 ? "G3" : "G2") + end + " I" + number(h.centre.x - start.x, 6) +
                         " J" + number(h.centre.y - start.y, 6);
            out_.emplace_back(h.n + join(motion, h.head) + h.tail, h.number);
            start = cutter_;
        }
        held_.clear();
        from_ = cutter_;
    }

    // The move held (the first held line that moves), or none.
    const Held* held_move() const {
        for (const Held& h : held_)
            if (h.move) return &h;
        return nullptr;
    }

    static std::string join(const std::string& a, const std::string& b) {
        return a.empty() ? b : a + " " + b;
    }

    // After G40 LinuxCNC's position is the programmed path's end while the cutter stands a radius
    // off it: the first move goes from the cutter to an end whose missing X or Y LinuxCNC takes
    // from the programmed end (a height change alone moves there too). It is written with both;
    // a move whose end cannot be written so is refused. The line is written without compensation
    // words where `turns_on` (a radius of 0).
    std::string after_off(const gcode::Line& l, const ReadLine& r, bool reframes,
                          const std::string& raw, bool turns_on) {
        const bool axes = l.has('X') || l.has('Y');
        const bool moves = motion_ >= 0 && motion_ <= 3 && (axes || l.has('Z') || has_motion(r));
        const bool cycle = motion_ > 3 && (axes || l.has('R'));
        if (!left_at_ || (!moves && !cycle && !reframes && !r.polar))
            return turns_on ? job_words::rebuilt_line(raw, r) : raw;
        if (cycle || reframes || r.polar || motion_ > 1)
            throw fail(
                "the first move after cutter radius compensation is turned off (G40) starts where "
                "the cutter stands, X" +
                number(left_at_->x, 4) + " Y" + number(left_at_->y, 4) +
                ", and LinuxCNC takes what it leaves out from the programmed path's end X" +
                number(programmed_.x, 4) + " Y" + number(programmed_.y, 4) +
                ": calbox writes that out for a straight move only; make it a G0 or G1 with both "
                "X and Y");
        const Point2 from = *left_at_;
        left_at_.reset();
        if (!absolute_) {
            // G91: from the programmed end, written as steps from where the cutter stands.
            const Point2 end{programmed_.x + l.value('X').value_or(0),
                             programmed_.y + l.value('Y').value_or(0)};
            return job_words::rebuilt_line(
                raw, r, " X" + number(end.x - from.x, 6) + " Y" + number(end.y - from.y, 6), "XY");
        }
        std::string missing;
        if (!l.has('X')) missing += " X" + number(programmed_.x, 6);
        if (!l.has('Y')) missing += " Y" + number(programmed_.y, 6);
        if (missing.empty()) return turns_on ? job_words::rebuilt_line(raw, r) : raw;
        return job_words::rebuilt_line(raw, r, missing);
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
    static constexpr double kHalfPi = pi / 2;
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
    bool from_known_ = true;
    // Where the cutter stands after G40 until a move says where it goes.
    std::optional<Point2> left_at_;  // where the held moves start is known (not after an entry arc)
};

}  // namespace

JobLines cutter_path(const JobLines& lines, std::optional<double> tool_radius_mm,
                     const ReadJobLine& read) {
    return CutterPath(tool_radius_mm, read).run(lines);
}

}  // namespace calbox::jobs
