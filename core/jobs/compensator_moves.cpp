// A line as the compensator writes it: a move cut into corrected pieces, a machine-coordinate
// move, a canned cycle kept (LinuxCNC) or written out as moves.
#include <algorithm>
#include <cmath>
#include <string>

#include "core/jobs/compensator.hpp"
#include "core/number_text.hpp"

namespace calbox::jobs::compensating {

void Compensator::emit(const std::string& text) {
    out_ += numbered_ ? numbering_.line(text, checksummed_) : text;
    out_ += '\n';
}

void Compensator::verbatim(std::string_view raw) {
    if (numbered_) {
        emit(body_of(raw));
    } else {
        out_ += raw;
        out_ += '\n';
    }
}

void Compensator::spindle_and_extruder_words(const gcode::Line& line) {
    if (has_m(line, 98) || has_m(line, 99))
        throw fail(
            "a subprogram call or return (M98, M99): have the CAM write the program "
            "flat");
    if (has_m(line, 6)) m_.spindle_turning = false;
    if (has_m(line, 3) || has_m(line, 4)) m_.spindle_turning = true;
    if (const auto s = line.value('S')) m_.spindle_speed = *s;
    if (has_m(line, 5)) m_.spindle_turning = false;
    if (has_m(line, 82)) m_.absolute_e = true;
    if (has_m(line, 83)) m_.absolute_e = false;
}

void Compensator::follow_z_and_extruder(const gcode::Line& line) {
    if (auto z = line.value('Z')) {
        m_.z_mm = m_.absolute ? *z * m_.unit_mm : m_.z_mm.value_or(0) + *z * m_.unit_mm;
        m_.written_z = m_.absolute ? *z : m_.written_z.value_or(0) + *z;
    }
    if (auto e = line.value('E')) m_.e = m_.absolute_e ? *e : m_.e + *e;
}

void Compensator::follow_other_axes(const gcode::Line& line) {
    for (const char a : kOtherAxes)
        if (auto v = line.value(a)) {
            const auto now = m_.other_axes.find(a);
            if (m_.absolute)
                m_.other_axes[a] = *v;
            else if (now != m_.other_axes.end())
                now->second += *v;
        }
}

void Compensator::not_an_xy_move(const std::string& raw, const gcode::Line& line, bool moves,
                                 bool drives_other_axes) {
    if (moves) follow_z_and_extruder(line);
    if (drives_other_axes) follow_other_axes(line);
    if (rewritten_)
        emit(*rewritten_ + trailing_comment(raw));
    else
        verbatim(raw);
}

namespace {

// A motion code (G0 to G3, G38, ...) or a canned cycle's among the line's codes.
bool commands_motion(const std::vector<Code>& codes) {
    return std::any_of(codes.begin(), codes.end(), [](Code c) {
        return c.is_motion() || (c.subcode < 0 && is_cycle(c.number));
    });
}

}  // namespace

gcode::Line Compensator::read_line(const std::string& raw, Polar& polar,
                                   std::vector<Code>& codes) const {
    try {
        gcode::Line line = gcode::parse_line(words_of(raw, &polar));
        codes = g_codes_of(line);
        return line;
    } catch (const gcode::SyntaxError& e) {
        throw fail(std::string(e.what()) +
                   (is_cnc(frame_.flavour)
                        ? ": " + controller_of(frame_.flavour) + " stops on it too"
                        : std::string()));
    }
}

void Compensator::refuse_feed_per_rev_at_rest(bool feeds) const {
    if (feeds && m_.feed_per_rev && m_.spindle_speed == 0)
        throw fail(
            "a feed per revolution (G95) with the spindle speed 0 (no S above 0): LinuxCNC "
            "stops on it (\"Cannot feed with zero spindle speed in feed per rev mode\")");
}

void Compensator::line(const std::string& raw) {
    std::vector<Code> codes;
    Polar polar;
    const gcode::Line line = read_line(raw, polar, codes);
    numbered_ = line.line_number.has_value();
    checksummed_ = gcode::without_checksum(raw).size() != raw.size();
    if (numbered_) numbering_.saw(*line.line_number);
    bool not_a_move = false;
    machine_move_ = false;
    motion_before_ = m_.motion;
    std::vector<Code> kept_codes;  // the line's other G words, written ahead of its move
    rewritten_.reset();
    state_words(line, codes, not_a_move, kept_codes);
    // The F in force, as the controller keeps it (G93's F is each move's own).
    if (auto f = line.value('F'); f && !m_.inverse_time) m_.feed = *f;
    if (is_cnc(frame_.flavour)) cnc_rules(line, codes, polar.any());
    spindle_and_extruder_words(line);

    const bool axes = line.has('X') || line.has('Y') || line.has('Z') || polar.any();
    const bool commanded_motion = commands_motion(codes);
    // A printer's M or T command is the line's one command; on LinuxCNC and grbl M, S, F and
    // T words ride on a move like any other word.
    const bool not_a_command =
        !is_cnc(frame_.flavour) && (line.command_letter == 'M' || line.command_letter == 'T');
    if (machine_move_) return machine_move(raw, line);
    const bool cycles = !not_a_move && !not_a_command && is_cycle(m_.motion) &&
                        (axes || line.has('R') || commanded_motion);
    const bool arc_words = line.has('I') || line.has('J') || line.has('K') || line.has('R');
    const bool is_arc_mode = m_.motion == 2 || m_.motion == 3;
    const bool moves = !not_a_move && m_.motion >= 0 && m_.motion <= 3 && !not_a_command &&
                       (axes || (is_arc_mode && (arc_words || commanded_motion)));
    refuse_feed_per_rev_at_rest(cycles || (moves && m_.motion != 0));
    if (cycles) return cycle(raw, line, polar, kept_codes);
    const bool moves_xy = moves && (is_arc_mode || line.has('X') || line.has('Y') || polar.any());
    if (!moves_xy) {
        if (polar.any()) throw fail("polar words ('@', '^') where no move takes them");
        return not_an_xy_move(raw, line, moves,
                              !not_a_move && !not_a_command && m_.motion >= 0 && m_.motion <= 3);
    }
    move(raw, line, polar, kept_codes, is_arc_mode);
}

void Compensator::machine_move(const std::string& raw, const gcode::Line& line) {
    if (!m_.absolute) throw fail("G53 in incremental mode (G91): LinuxCNC refuses it too");
    Point2 to = m_.xy_mm;
    if (!m_.xy_known && !(line.has('X') && line.has('Y'))) {
        verbatim(raw);  // one axis of a place the file does not give: still unknown
        m_.xy_known = false;
        return;
    }
    if (auto x = line.value('X')) to.x = *x * m_.unit_mm;
    if (auto y = line.value('Y')) to.y = *y * m_.unit_mm;
    if (!frame_.travel_mm.contains(to))
        throw fail("the machine-coordinate move (G53) to X" + number(to.x, 3) + " Y" +
                   number(to.y, 3) + " mm is beyond the machine's travel");
    if (line.has('Z')) {
        // G53's Z is the machine's, not the job's: the job's height is not known after it.
        m_.z_mm.reset();
        m_.written_z.reset();
    }
    reframe([&] {
        m_.xy_mm = to;
        m_.xy_known = true;
    });
    if (const auto offset = m_.offset_mm()) m_.written_xy = job_of(to, *offset);
    verbatim(raw);
}

std::vector<PathPoint> Compensator::pieces_of(const gcode::Line& line, bool is_arc_mode,
                                              Point2 from, Point2 to, std::optional<double> z_from,
                                              std::optional<double> z_to) const {
    const double r_tolerance_mm = written_precision_ * m_.unit_mm;
    // A helix shares its descent along its chords; from a height the file has not given,
    // each chord would take the whole of it at once (a straight move is written whole for
    // that; an arc cannot be).
    if (is_arc_mode && m_.plane == 17 && line.has('Z') && !z_from)
        throw fail(
            "an arc that changes height (a helix) from a height the file has not given: its "
            "chords cannot share the descent; give a Z move before it");
    // In the XZ or YZ plane the height is one of the arc's own coordinates: from a height the
    // file has not given, its centre and its path are not known (rs274 takes Z0 there; a
    // machine starts where its tool is).
    if (is_arc_mode && m_.plane != 17 && !z_from)
        throw fail(std::string("an arc in the ") + (m_.plane == 18 ? "XZ" : "YZ") +
                   " plane from a height the file has not given: its centre and path are "
                   "not known; give a Z move before it");
    const auto failing = [this](const std::string& why) { return fail(why); };
    return is_arc_mode
               ? arc_path(line, m_, from, to, z_from, z_to, settings_, r_tolerance_mm, failing)
               // From a height the file has not given, a climb cannot be shared along pieces
               // (each would take the whole of it at once): the move is written whole, to its
               // corrected end, as one from a place not given is.
               : line_path(m_.xy_known && !(line.has('Z') && !z_from), from, to, z_from, z_to,
                           settings_);
}

std::vector<OtherAxis> Compensator::other_axes_driven(const gcode::Line& line, std::size_t pieces) {
    std::vector<OtherAxis> others;
    for (const char a : kOtherAxes) {
        const auto v = line.value(a);
        if (!v) continue;
        const auto now = m_.other_axes.find(a);
        if (now == m_.other_axes.end()) {
            if (pieces > 1)
                throw fail(std::string("a move that drives ") + a +
                           " from where the file has not said: it cannot be shared along "
                           "the move's pieces (give " +
                           a + " on an earlier move, or G92 " + a + ")");
            if (m_.absolute) m_.other_axes[a] = *v;
            continue;
        }
        others.push_back({a, now->second, m_.absolute ? *v : now->second + *v});
    }
    return others;
}

void Compensator::move(const std::string& raw, const gcode::Line& line, const Polar& polar,
                       const std::vector<Code>& kept_codes, bool is_arc_mode) {
    if (line.block_delete)
        throw fail("a move under block delete ('/'): whether it runs is the operator's switch");
    if (!m_.xy_known && !(m_.absolute && line.has('X') && line.has('Y') && !polar.any()))
        throw fail(
            "a move that gives one axis where the other's position is unknown (after G28 or at "
            "the start)");
    const Point2 offset = offset_or_fail("a move");
    const Point2 from = m_.xy_mm;
    const Point2 to = end_of(line, polar, offset);
    const std::optional<double> z_from = m_.z_mm;
    std::optional<double> z_to = m_.z_mm;
    if (auto z = line.value('Z'))
        z_to = m_.absolute ? *z * m_.unit_mm : m_.z_mm.value_or(0) + *z * m_.unit_mm;
    const std::optional<double> e_word = line.value('E');
    const std::vector<PathPoint> path = pieces_of(line, is_arc_mode, from, to, z_from, z_to);
    // The move's end as the job writes it; then, for an arc, every chord's end (an arc
    // bulges past the rectangle its ends lie in).
    inside_travel(to, offset);
    for (const auto& p : path) inside_travel(p.xy, offset);
    if (is_arc_mode) ++report_.arcs;
    ++report_.moves;
    const bool moves_z = z_to.has_value() && (line.has('Z') || (is_arc_mode && m_.plane != 17));
    const std::string command = m_.motion == 0 ? "G0" : "G1";
    const double e_from = m_.e;
    const double e_total = e_word ? (m_.absolute_e ? *e_word - m_.e : *e_word) : 0;
    const std::size_t n = path.size();
    const std::vector<OtherAxis> others = other_axes_driven(line, n);
    const CommandWords commands = command_words(line);
    for (std::size_t k = 0; k < n; ++k) {
        const double share = static_cast<double>(k + 1) / static_cast<double>(n);
        const Point2 c = corrected(path[k].xy);
        std::string text;
        if (k == 0)
            for (const Code code : kept_codes) text += code.text() + " ";
        text += command;
        text += xy_words(c, offset, decimals());
        if (moves_z && path[k].z_mm) text += z_word(*path[k].z_mm);
        if (e_word) {
            text += " E" + number(m_.absolute_e ? e_from + e_total * share
                                                : e_total / static_cast<double>(n),
                                  5);
        }
        for (const auto& a : others) {
            text += ' ';
            text += a.letter;
            text += number(m_.absolute ? a.from + (a.to - a.from) * share
                                       : (a.to - a.from) / static_cast<double>(n),
                           6);
        }
        const auto feed = line.value('F');
        const bool per_piece_feed = m_.inverse_time && feed && m_.motion != 0;
        std::string left_out = per_piece_feed ? "XYZEIJKRGFM" : "XYZEIJKRGM";
        for (const auto& a : others) left_out += a.letter;
        if (is_arc_mode) left_out += 'P';  // the turns, traced
        if (k == 0) text += other_words(line, left_out) + commands.before;
        if (per_piece_feed) text += " F" + number(*feed * static_cast<double>(n), 6);
        if (k + 1 == n) text += commands.after;
        if (k + 1 == n) text += trailing_comment(raw);
        emit(text);
        ++report_.pieces;
    }
    m_.xy_mm = to;
    m_.xy_known = true;
    m_.z_mm = z_to;
    if (e_word) m_.e = m_.absolute_e ? *e_word : m_.e + *e_word;
    for (const auto& a : others) m_.other_axes[a.letter] = a.to;
}

std::string Compensator::other_words(const gcode::Line& line, std::string_view left_out) {
    std::string text;
    for (const auto& w : line.parameters) {
        if (left_out.find(w.letter) != std::string_view::npos) continue;
        text += ' ';
        text += w.letter;
        if (w.value) text += number(*w.value, 6);
    }
    return text;
}

void Compensator::take_cycle_words(const gcode::Line& line) {
    if (line.block_delete)
        throw fail(
            "a drilling cycle under block delete ('/'): whether it runs is the "
            "operator's switch");
    if (m_.plane != 17)
        throw fail("a drilling cycle in the XZ or YZ plane (G18, G19): holes along X or Y");
    // R, Z, Q and P stay in force only while the same cycle does: a cycle entered anew (after
    // G80, another motion or another cycle) gives its own, as LinuxCNC asks ("R clearance
    // plane unspecified in cycle").
    if (motion_before_ != m_.motion)
        m_.cycle_r.reset(), m_.cycle_z.reset(), m_.cycle_q.reset(), m_.cycle_p.reset();
    if (auto r = line.value('R')) m_.cycle_r = *r;
    if (auto z = line.value('Z')) m_.cycle_z = *z;
    if (auto q = line.value('Q')) m_.cycle_q = *q;
    if (auto p = line.value('P')) m_.cycle_p = *p;
    const Code code{m_.motion, -1};
    if (!m_.cycle_r || !m_.cycle_z)
        throw fail("canned cycle " + code.text() +
                   " without its R or Z (retract plane and bottom of the hole): a cycle "
                   "entered anew gives its own, LinuxCNC keeps them only while the same "
                   "cycle goes on");
    if (dwells_at_bottom(m_.motion) && !m_.cycle_p)
        throw fail("canned cycle " + code.text() +
                   " without its dwell (P): LinuxCNC stops on it (\"Dwell time p word "
                   "missing\")");
    if ((m_.motion == 86 || m_.motion == 88) && !m_.spindle_turning)
        throw fail("canned cycle " + code.text() +
                   " with the spindle not turning (no M3 or M4 since the start, an M5 or a tool "
                   "change): "
                   "LinuxCNC stops on it (\"Spindle not turning\")");
    // A retract plane below the hole's bottom drills upwards: LinuxCNC stops on it. Under
    // G91 Z is taken from R, so a Z above 0 is the same.
    if (m_.absolute ? *m_.cycle_r < *m_.cycle_z : *m_.cycle_z > 0)
        throw fail("canned cycle " + code.text() + " with its retract plane R" +
                   number(*m_.cycle_r, 4) + " below the hole's bottom Z" + number(*m_.cycle_z, 4) +
                   (m_.absolute ? "" : " (G91: Z from R)") +
                   ": it would drill upwards; LinuxCNC stops on it (\"R less than z in cycle "
                   "in xy plane\")");
}

void Compensator::cycle(const std::string& raw, const gcode::Line& line, const Polar& polar,
                        const std::vector<Code>& kept_codes) {
    take_cycle_words(line);
    const Code code{m_.motion, -1};
    const double repeats = line.value('L').value_or(1);
    if (!(repeats >= 0 && repeats <= 10000 && repeats == std::floor(repeats)))
        throw fail("canned cycle " + code.text() + " L" + number(repeats, 3) +
                   ": L repeats a hole 0 to 10000 times");
    const bool keep = frame_.flavour == Flavour::linuxcnc;
    if (!m_.xy_known && !(m_.absolute && line.has('X') && line.has('Y') && !polar.any()))
        throw fail("a drilling cycle where the position is unknown (after G28 or at the start)");
    const Point2 offset = offset_or_fail("a drilling cycle");
    // The planes in the job's frame, mm, fixed for the block: G91 takes R from the height
    // the series of cycles started at (as LinuxCNC reads it: a later block's R0 is that
    // height again, not the retract it starts from), Z from R.
    std::optional<double> r_mm, bottom_mm;
    if (m_.absolute) {
        r_mm = *m_.cycle_r * m_.unit_mm;
        bottom_mm = *m_.cycle_z * m_.unit_mm;
    } else if (m_.cycle_start_z_mm) {
        r_mm = *m_.cycle_start_z_mm + *m_.cycle_r * m_.unit_mm;
        bottom_mm = *r_mm + *m_.cycle_z * m_.unit_mm;
    } else if (!keep) {
        throw fail("canned cycle " + code.text() +
                   " in incremental mode (G91) from a height the file does not give: give a "
                   "Z move before it");
    }
    std::optional<double> clear_mm = r_mm;
    if (!m_.retract_to_r)
        clear_mm = m_.cycle_start_z_mm && r_mm
                       ? std::optional<double>(std::max(*m_.cycle_start_z_mm, *r_mm))
                       : std::nullopt;
    const CommandWords commands = command_words(line);
    for (long k = 0; k < static_cast<long>(repeats); ++k) {
        const Point2 hole = end_of(line, polar, offset);
        inside_travel(hole, offset);
        const Point2 c = corrected(hole);
        if (keep) {
            std::string text;
            if (k == 0)
                for (const Code kc : kept_codes) text += kc.text() + " ";
            text += code.text();
            text += xy_words(c, offset, decimals());
            // R stays in force from block to block, as the job's own repeats keep it (under
            // G91 it is taken from the series' start either way).
            if (k == 0 && line.has('R')) text += " R" + number(*line.value('R'), 6);
            text += other_words(line, k == 0 ? "XYRLGM" : "XYRLGFM");
            if (k == 0) text += commands.before;
            if (k + 1 == static_cast<long>(repeats)) text += commands.after + trailing_comment(raw);
            emit(text);
        } else {
            if (k == 0 && !commands.before.empty()) emit(commands.before.substr(1));
            // Written out in absolute coordinates; an incremental job goes back to G91.
            const bool incremental = !m_.absolute;
            if (incremental) emit("G90"), m_.absolute = true;
            written_out_cycle(c, offset, *r_mm, *bottom_mm, clear_mm, line, kept_codes, k == 0);
            if (incremental) emit("G91"), m_.absolute = false;
            if (k + 1 == static_cast<long>(repeats) && !commands.after.empty())
                emit(commands.after.substr(1));
            if (k + 1 == static_cast<long>(repeats)) {
                const std::string comment = gcode::comments_of(gcode::without_checksum(raw));
                if (!comment.empty()) emit(comment);
            }
        }
        ++report_.holes;
        ++report_.pieces;
        m_.xy_mm = hole;
        m_.xy_known = true;
        m_.z_mm = clear_mm;
        m_.written_z.reset();
    }
    if (repeats == 0) verbatim(raw);
}

void Compensator::written_out_pecks(double r_mm, double bottom_mm) {
    const Code code{m_.motion, -1};
    const int d = decimals();
    const auto z = [&](double mm) { return " Z" + number(mm / m_.unit_mm, d); };
    const double peck_clearance_mm = 0.254;  // LinuxCNC's: 0.010 inch
    const double q_mm = m_.cycle_q.value_or(0) * m_.unit_mm;
    if (!(q_mm > 0)) throw fail("canned cycle " + code.text() + " needs a peck depth Q above 0");
    double depth = r_mm;
    while (depth > bottom_mm + 1e-9) {
        const double next = std::max(depth - q_mm, bottom_mm);
        if (depth < r_mm && m_.motion == 83) emit("G0" + z(depth + peck_clearance_mm));
        emit("G1" + z(next));
        depth = next;
        if (depth > bottom_mm + 1e-9)
            emit("G0" + z(m_.motion == 83 ? r_mm : depth + peck_clearance_mm));
    }
}

void Compensator::written_out_cycle(Point2 c, Point2 offset, double r_mm, double bottom_mm,
                                    std::optional<double> clear_mm, const gcode::Line& line,
                                    const std::vector<Code>& kept_codes, bool first) {
    const Code code{m_.motion, -1};
    if (!clear_mm)
        throw fail("canned cycle " + code.text() +
                   " under G98 returns to the height before the cycles, which the file does "
                   "not give: have the CAM write G99, or a Z move before it");
    const int d = decimals();
    const auto z = [&](double mm) { return " Z" + number(mm / m_.unit_mm, d); };
    std::string head;
    if (first)
        for (const Code kc : kept_codes)
            // G91 is written after the hole, which is written in G90.
            if (!kc.is(98) && !kc.is(99) && !kc.is(91)) head += kc.text() + " ";
    // The block's F is set on its first line, before any of its moves, as the cycle set it.
    std::string feed;
    if (auto f = line.value('F'); f && first) feed = " F" + number(*f, 6);
    if (m_.z_mm && *m_.z_mm < r_mm) emit(head + "G0" + z(r_mm) + feed), head.clear(), feed.clear();
    emit(head + "G0" + xy_words(c, offset, d) + feed);
    if (!m_.z_mm || *m_.z_mm != r_mm) emit("G0" + z(r_mm));
    const auto down = [&](double to_mm) { emit("G1" + z(to_mm)); };
    switch (m_.motion) {
        case 81:
            down(bottom_mm);
            break;
        case 82:
        case 89:
            down(bottom_mm);
            emit("G4 P" + number(m_.cycle_p.value_or(0), 4));
            if (m_.motion == 89) emit("G1" + z(r_mm));
            break;
        case 85:
            down(bottom_mm);
            emit("G1" + z(r_mm));
            break;
        case 73:
        case 83:
            written_out_pecks(r_mm, bottom_mm);
            break;
        default:
            throw fail("canned cycle " + code.text() +
                       " (tapping, boring with a spindle stop, back boring or a manual "
                       "retract) on a controller without cycles: have the CAM write it out");
    }
    emit("G0" + z(*clear_mm));
}

}  // namespace calbox::jobs::compensating
