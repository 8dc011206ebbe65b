// The compensator's frame: the job's coordinates as the machine's (work systems, G92, G52, G10
// offsets, units, the placed turn), the travel, and the X Y Z words written back.
#include <cmath>
#include <numbers>
#include <string>

#include "core/jobs/compensator.hpp"
#include "core/number_text.hpp"

namespace calbox::jobs::compensating {

Point2 Compensator::offset_or_fail(const char* doing) const {
    const auto offset = m_.offset_mm();
    if (!offset) {
        static const char* names[] = {"G54", "G55",   "G56",   "G57",  "G58",
                                      "G59", "G59.1", "G59.2", "G59.3"};
        const std::string name = names[m_.work_system];
        throw fail(std::string(doing) + " in " + name +
                   ", whose zero the controller holds and the file does not set: give it "
                   "(calbox compensate --work-zero " +
                   name + "=X,Y, machine coordinates) or set it in the job (G10 L2)");
    }
    return *offset;
}

Point2 Compensator::placed(Point2 p) const {
    if (frame_.turn_rad == 0 && frame_.scale == 1) return p;
    const Point2 pivot = *frame_.work_zero_mm[0];
    const double c = frame_.scale * std::cos(frame_.turn_rad),
                 s = frame_.scale * std::sin(frame_.turn_rad);
    const Point2 d{p.x - pivot.x, p.y - pivot.y};
    return {pivot.x + c * d.x - s * d.y, pivot.y + s * d.x + c * d.y};
}

void Compensator::refuse_when_turned(const std::string& what) const {
    if (frame_.turn_rad != 0 || frame_.scale != 1)
        throw fail(what +
                   " in a job placed turned with the stock (--work-zero camera, --register): "
                   "the turn is about G54's zero as the camera gives it; have the CAM write "
                   "the job in G54 alone, without offsets of its own");
}

void Compensator::inside_travel(Point2 unplaced, Point2 offset) const {
    const Point2 p = placed(unplaced);
    if (frame_.travel_mm.contains(p)) return;
    const Point2 job = job_of(unplaced, offset);
    const auto& t = frame_.travel_mm;
    throw fail("the point X" + number(job.x, 4) + " Y" + number(job.y, 4) + " is at machine X" +
               number(p.x, 3) + " Y" + number(p.y, 3) + " mm, beyond the machine's travel (X " +
               number(t.min_x_mm, 3) + ".." + number(t.max_x_mm, 3) + ", Y " +
               number(t.min_y_mm, 3) + ".." + number(t.max_y_mm, 3) +
               " mm): check the job's work zero, or the travel in the machine file");
}

Point2 Compensator::end_of(const gcode::Line& line, const Polar& polar, Point2 offset) const {
    const Point2 from = m_.xy_mm;
    if (polar.any()) {
        const Point2 now = job_of(from, offset);
        const double r_now = std::hypot(now.x, now.y);
        const double a_now = std::atan2(now.y, now.x) * 180 / std::numbers::pi;
        const double r =
            m_.absolute ? polar.distance.value_or(r_now) : r_now + polar.distance.value_or(0);
        const double a =
            (m_.absolute ? polar.angle_deg.value_or(a_now) : a_now + polar.angle_deg.value_or(0)) *
            std::numbers::pi / 180;
        return machine_of({r * std::cos(a), r * std::sin(a)}, offset);
    }
    Point2 to = from;
    if (auto x = line.value('X'))
        to.x = m_.absolute ? *x * m_.unit_mm + offset.x : from.x + *x * m_.unit_mm;
    if (auto y = line.value('Y'))
        to.y = m_.absolute ? *y * m_.unit_mm + offset.y : from.y + *y * m_.unit_mm;
    return to;
}

std::string Compensator::xy_words(Point2 corrected_mm, Point2 offset, int decimals) {
    const Point2 job_xy = job_of(corrected_mm, offset);
    if (m_.absolute) {
        m_.written_xy = job_xy;
        return " X" + number(job_xy.x, decimals) + " Y" + number(job_xy.y, decimals);
    }
    const double dx = std::stod(number(job_xy.x - m_.written_xy.x, decimals));
    const double dy = std::stod(number(job_xy.y - m_.written_xy.y, decimals));
    m_.written_xy = {m_.written_xy.x + dx, m_.written_xy.y + dy};
    return " X" + number(dx, decimals) + " Y" + number(dy, decimals);
}

std::string Compensator::z_word(double z_mm) {
    const double z_job = z_mm / m_.unit_mm;
    if (m_.absolute || !m_.written_z) {
        m_.written_z = z_job;
        return " Z" + number(z_job, decimals());
    }
    const double dz = std::stod(number(z_job - *m_.written_z, decimals()));
    *m_.written_z += dz;
    return " Z" + number(dz, decimals());
}

void Compensator::work_offsets(const gcode::Line& line) {
    const auto l = line.value('L');
    const bool printer = frame_.flavour == Flavour::printer;
    if (!l) {
        if (printer) {
            // Marlin, RepRapFirmware and Klipper: firmware retraction. RepRapFirmware's
            // G10 P sets a tool's offsets or temperatures; offsets move the tool in XY.
            if (line.has('P') && (line.has('X') || line.has('Y')))
                throw fail(
                    "G10 P with X or Y sets a tool's offset in the controller: the "
                    "tool's place is not in the file");
            return;
        }
        throw fail("G10 without L: set a work offset with G10 L2 or G10 L20");
    }
    if (*l == 1 || *l == 10 || *l == 11) return;  // the tool table: lengths, not XY
    if (*l != 2 && *l != 20)
        throw fail("G10 L" + number(*l, 3) + ": calbox tracks work offsets set by L2 and L20");
    if (line.value('R').value_or(0) != 0)
        throw fail("G10 with R rotates a work system: have the CAM write the rotated job");
    const double p = line.value('P').value_or(0);
    if (!(p >= 0 && p <= 9 && p == std::floor(p)))
        throw fail("G10 L" + number(*l, 0) + " P" + number(p, 3) +
                   ": P is 0 (the system in use) or 1 to 9 (G54 to G59.3)");
    const std::size_t system = p == 0 ? m_.work_system : static_cast<std::size_t>(p) - 1;
    const auto x = line.value('X'), y = line.value('Y');
    if (!x && !y) return;
    refuse_when_turned("G10 L" + number(*l, 0) + " with X or Y");
    reframe([&] {
        auto& zero = m_.work_zero_mm[system];
        if (*l == 2) {
            // Machine coordinates of the system's zero (G91 has no effect on L2).
            if ((!x || !y) && !zero)
                throw fail("G10 L2 sets one axis of a work system whose zero is not known");
            Point2 z = zero.value_or(Point2{});
            if (x) z.x = *x * m_.unit_mm;
            if (y) z.y = *y * m_.unit_mm;
            zero = z;
        } else {
            // The zero that makes the current position read X Y in that system.
            if (!m_.xy_known)
                throw fail(
                    "G10 L20 before the position is known (after G28 or at the "
                    "start)");
            if ((!x || !y) && !zero)
                throw fail("G10 L20 sets one axis of a work system whose zero is not known");
            // The controller stands where it was sent, the corrected point: the line is
            // rewritten so that the zero it sets is the intended one.
            const Point2 sent = machine_of(m_.written_xy, offset_or_fail("G10 L20"));
            Point2 z = zero.value_or(Point2{});
            if (x) z.x = m_.xy_mm.x - m_.g92_offset_mm.x - *x * m_.unit_mm;
            if (y) z.y = m_.xy_mm.y - m_.g92_offset_mm.y - *y * m_.unit_mm;
            zero = z;
            rewritten_ = offset_line(line, {(sent.x - m_.g92_offset_mm.x - z.x) / m_.unit_mm,
                                            (sent.y - m_.g92_offset_mm.y - z.y) / m_.unit_mm});
        }
    });
}

void Compensator::state_words(const gcode::Line& line, const std::vector<Code>& codes,
                              bool& not_a_move, std::vector<Code>& kept_codes) {
    for (const Code c : codes) {
        if (const auto why = refused_word(c, line, frame_.flavour); !why.empty()) throw fail(why);
        if (c.is_motion() || (c.subcode < 0 && is_cycle(c.number))) {
            if (is_cycle(c.number) && !is_cycle(m_.motion)) m_.cycle_start_z_mm = m_.z_mm;
            m_.motion = c.number;
            continue;
        }
        kept_codes.push_back(c);
        if (!mode_word(c)) offset_word(line, c, not_a_move);
    }
}

bool Compensator::mode_word(Code c) {
    if (c.is(20) || c.is(21)) {
        reframe([&] { m_.unit_mm = c.is(20) ? 25.4 : 1; });
    } else if (c.is(90)) {
        m_.absolute = true;
    } else if (c.is(91)) {
        m_.absolute = false;
    } else if (c.is(17) || c.is(18) || c.is(19)) {
        m_.plane = c.number;
    } else if (c.is(80)) {
        m_.motion = -1;
    } else if (c.is(93) || c.is(94) || c.is(95)) {
        m_.inverse_time = c.is(93);
        m_.feed_per_rev = c.is(95);
    } else if (c.is(98) || c.is(99)) {
        m_.retract_to_r = c.is(99);
    } else if ((c.number >= 54 && c.number <= 58 && c.subcode < 0) ||
               (c.number == 59 && c.subcode <= 3)) {
        const std::size_t system = c.number == 59 && c.subcode > 0
                                       ? static_cast<std::size_t>(5 + c.subcode)
                                       : static_cast<std::size_t>(c.number - 54);
        if (system != 0) refuse_when_turned(c.text());
        reframe([&] { m_.work_system = system; });
    } else {
        return false;
    }
    return true;
}

void Compensator::g92_cleared_or_restored(Code c) {
    if (c.subcode != 1 && c.subcode != 2 && c.subcode != 3)
        throw fail(c.text() + " is no offset code");
    // No axis words of its own: a move on its line runs in the frame it leaves.
    if (frame_.flavour == Flavour::grbl && c.subcode != 1)
        throw fail(c.text() + ": grbl has G92.1 only (its error 20)");
    if (c.subcode == 3 && !m_.saved_g92_mm)
        throw fail(
            "G92.3 restores an offset the file did not set (the controller's "
            "parameters hold it)");
    const Point2 to = c.subcode == 3 ? *m_.saved_g92_mm : Point2{};
    reframe([&] { m_.g92_offset_mm = to; });
    if (c.subcode == 1) m_.saved_g92_mm = Point2{};
}

void Compensator::g52_local_offset(const gcode::Line& line) {
    // LinuxCNC's local offset: the G92 offset set to the words given, not from where the tool
    // is, so the controller's frame and the intended one stay the same.
    reframe([&] {
        if (auto x = line.value('X')) m_.g92_offset_mm.x = *x * m_.unit_mm;
        if (auto y = line.value('Y')) m_.g92_offset_mm.y = *y * m_.unit_mm;
    });
}

void Compensator::offset_word(const gcode::Line& line, Code c, bool& not_a_move) {
    if (c.is(10)) {
        not_a_move = true;
        work_offsets(line);
    } else if (c.is(11)) {
        not_a_move = true;
    } else if (c.is(53)) {
        // Machine coordinates for this line: the controller's own places (parking,
        // tool change), passed as written.
        machine_move_ = line.has('X') || line.has('Y');
    } else if (c.is(92)) {
        not_a_move = true;
        g92_sets_offset(line);
    } else if (c.number == 92) {
        g92_cleared_or_restored(c);
    } else if (c.is(52)) {
        not_a_move = true;
        g52_local_offset(line);
    } else if (c.is(28) || c.is(30)) {
        not_a_move = true;
        m_.xy_known = false, m_.z_mm.reset(), m_.written_z.reset();
        m_.other_axes.clear();
    } else if (c.is(4)) {
        // LinuxCNC and grbl dwell, then move the line's axis words under the motion in
        // force; a printer's G4 is the line's one command.
        not_a_move = not_a_move || !is_cnc(frame_.flavour) ||
                     !(line.has('X') || line.has('Y') || line.has('Z'));
    } else if (c.number == 38) {
        if (line.has('X') || line.has('Y'))
            throw fail("a probing move (" + c.text() +
                       ") with X or Y: where it stops is not known");
        not_a_move = true;
    }
}

// G92 with axis words: the tool said to stand at them, wherever it stands.
void Compensator::g92_sets_offset(const gcode::Line& line) {
    if (line.has('X') || line.has('Y')) {
        refuse_when_turned("G92 with X or Y");
        if (!m_.xy_known)
            throw fail(
                "G92 with X or Y before the position is known: it says the tool is "
                "there, wherever it stands; give where it stands when the job starts "
                "(calbox compensate --start-at X,Y, machine coordinates)");
        offset_or_fail("G92");
        const Point2 zero = *m_.work_zero_mm[m_.work_system];
        reframe([&] {
            if (auto x = line.value('X'))
                m_.g92_offset_mm.x = m_.xy_mm.x - zero.x - *x * m_.unit_mm;
            if (auto y = line.value('Y'))
                m_.g92_offset_mm.y = m_.xy_mm.y - zero.y - *y * m_.unit_mm;
        });
        m_.saved_g92_mm = m_.g92_offset_mm;
        // The controller stands at the corrected point: said to read there what the
        // written position reads in the intended frame, its offset is the intended one.
        rewritten_ = offset_line(line, m_.written_xy);
    }
    if (auto e = line.value('E')) m_.e = *e;
    if (auto z = line.value('Z')) m_.z_mm = *z * m_.unit_mm, m_.written_z = *z;
    for (const char a : kOtherAxes)
        if (auto v = line.value(a)) m_.other_axes[a] = *v;
}

std::string Compensator::offset_line(const gcode::Line& line, Point2 xy) const {
    std::string text;
    for (const Code c : g_codes_of(line)) {
        if (!text.empty()) text += ' ';
        text += c.text();
    }
    for (const auto& w : line.parameters) {
        if (w.letter == 'G' || w.letter == 'M') continue;
        text += ' ';
        text += w.letter;
        if (w.letter == 'X' || w.letter == 'Y')
            text += number(w.letter == 'X' ? xy.x : xy.y, decimals());
        else if (w.value)
            text += number(*w.value, 6);
    }
    const CommandWords m = command_words(line);
    text += m.before + m.after;
    return text;
}

}  // namespace calbox::jobs::compensating
