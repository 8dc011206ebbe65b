#pragma once
// The compensator's own pieces (core/jobs/compensate*.cpp and controller_words.cpp, job_path.cpp):
// what the controller holds between lines, what each controller reads, a move's pieces, and the
// Compensator that reads a job line by line as its controller would and writes it corrected.
// Internal to compensate_gcode: nothing outside core/jobs includes it.
#include <array>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/gcode/gcode_line.hpp"
#include "core/jobs/compensate.hpp"
#include "core/jobs/job_words.hpp"

namespace calbox::jobs::compensating {

using geometry::Point2;
using job_words::Code;
using job_words::command_words;
using job_words::CommandWords;
using job_words::g_codes_of;
using job_words::has_m;
using job_words::has_m_in;
using job_words::is_cycle;
using job_words::kOtherAxes;
using job_words::number;
using job_words::ReadLine;
using job_words::trailing_comment;

// What the controller holds between lines, as the job's lines set it. XY are kept in machine
// coordinates (the work system's zero and G92 applied), in mm; Z in the job's own frame, in mm
// (the correction does not move it; a move's pieces share it).
struct Modal {
    int motion = -1;  // 0..3, a canned cycle (73, 81..89), -1 before any and after G80
    bool absolute = true, absolute_e = true;
    double unit_mm = 1;  // 25.4 after G20
    int plane = 17;
    std::size_t work_system = 0;  // G54
    std::array<std::optional<Point2>, kWorkSystems> work_zero_mm;
    Point2 g92_offset_mm;
    // What G92.3 restores: the offset G92 last set (LinuxCNC's parameters 5211-5216), zero after
    // G92.1; unknown before the file sets one.
    std::optional<Point2> saved_g92_mm;
    Point2 xy_mm;
    bool xy_known = false;  // not until a move gives both axes (and not after G28)
    std::optional<double> z_mm;
    double e = 0;
    // The other axes' positions (rotary A B C, linear U V W), in the job's units, where known:
    // a move that drives one is shared along its pieces as Z is.
    std::map<char, double> other_axes;
    // The position last written, in the job's units and frame: relative moves are written as
    // differences of it, so that rounding never accumulates.
    Point2 written_xy;
    std::optional<double> written_z;
    // Canned cycles: G99 retracts to R, G98 to the height before the series of cycles (or R,
    // when that is lower); their R, Z, Q and P stay in force from block to block.
    bool retract_to_r = false;
    // G93: F is each move's inverse time (1 / minutes), so a move split in n pieces takes n F.
    bool inverse_time = false;
    std::optional<double> feed;  // the F in force (units per minute), where a line gave one
    std::optional<double> cycle_start_z_mm;
    std::optional<double> cycle_r, cycle_z, cycle_q, cycle_p;  // the job's units
    // Whether the file has the spindle turning (M3, M4; M5 and a tool change stop it), as
    // LinuxCNC's interpreter follows it from a stopped start: G86 and G88 need it turning.
    bool spindle_turning = false;
    // G95 (feed per revolution) and the S in force: LinuxCNC feeds by neither with S at 0.
    bool feed_per_rev = false;
    double spindle_speed = 0;

    // Machine = job * unit + offset, where the work system's zero is known.
    std::optional<Point2> offset_mm() const {
        const auto& zero = work_zero_mm[work_system];
        if (!zero) return std::nullopt;
        return Point2{zero->x + g92_offset_mm.x, zero->y + g92_offset_mm.y};
    }
};

struct PathPoint {
    Point2 xy;                   // the calibrated frame, mm
    std::optional<double> z_mm;  // the job's frame
};

// A job whose lines were numbered comes out numbered, from its first number on, by its own step,
// with a checksum where the line had one.
struct Numbering {
    std::optional<long> first, step, next;
    void saw(long number) {
        if (!first) {
            first = next = number;
        } else if (!step) {
            step = std::max(1L, number - *first);
            next = *first + *step;
        }
    }
    std::string line(const std::string& body, bool checksummed) {
        const long n = *next;
        next = n + step.value_or(1);
        if (checksummed) return gcode::numbered_line(n, body);
        std::string out = "N";  // appended piece by piece: see Code::text()
        out += std::to_string(n);
        out += ' ';
        out += body;
        return out;
    }
};

// The polar words of a line (LinuxCNC's '@' distance and '^' angle in degrees), taken out of it.
struct Polar {
    std::optional<double> distance, angle_deg;
    bool any() const { return distance || angle_deg; }
};

// An axis other than X Y Z a move drives (rotary A B C, linear U V W), in the job's units.
struct OtherAxis {
    char letter;
    double from, to;
};

// How a piece of the compensator names a refusal: with the line it stands on.
using Failure = std::function<CompensateError(const std::string&)>;

// The raw line without its line number and checksum, comments kept.
std::string body_of(std::string_view raw);

// The drilling cycles that dwell at the hole's bottom, for their P.
bool dwells_at_bottom(int motion);

Polar take_polar_words(std::string& raw);

// The most decimals written in the line's words `letters`: the file's written precision there.
int written_decimals(std::string_view raw, std::string_view letters);

// A word that changes what a job's coordinates mean, or names a machine calbox does not
// compensate: why it is refused, or "".
bool is_lathe_word(const Code& c);

bool is_cnc(Flavour f);

// The letters each CNC controller has: LinuxCNC's interpreter stops on any other ("Bad
// character"), grbl with its error 20. U V W on LinuxCNC: machines configured with them exist,
// though rs274's own default machine (XYZABC) refuses them. grbl's Q: the peck of the drilling
// cycles calbox writes out for it as moves; its D and H are read to be refused with the code
// they belong to (cutter compensation, tool length), which says more than the letter.
std::string_view letters_of(Flavour f);

std::string controller_of(Flavour f);

// A G code's modal group, as RS274NGC numbers them (0 the non-modal codes), or -1 for a code
// outside the table.
int modal_group(const Code& c);

// LinuxCNC's G codes (its G-code reference; grbl's are a subset): any other stops its
// interpreter ("Unknown g code used"), so calbox never passes one on as written.
bool is_known_code(const Code& c);

// The M codes each controller has: LinuxCNC's (its M-code reference, user codes M100-M199
// included) and grbl 1.1's (its gcode.c; any other is its error 20, a tool change M6 too).
bool is_known_m(Flavour f, double value);

std::string refused_word(const Code& c, const gcode::Line& line, Flavour flavour);
// A straight move's pieces, from the start (excluded) to the end.
std::vector<PathPoint> line_path(bool start_known, Point2 from, Point2 to,
                                 std::optional<double> z_from, std::optional<double> z_to,
                                 const CompensateSettings& settings);

std::vector<PathPoint> arc_path(const gcode::Line& line, const Modal& m, Point2 from, Point2 to,
                                std::optional<double> z_from, std::optional<double> z_to,
                                const CompensateSettings& settings, double r_tolerance_mm,
                                const Failure& fail);

// Where to command for the tool to land on machine point `p`: the correction inside the
// measured area, and its nearest edge point's correction beyond it (held, never extrapolated),
// each held point counted in `report`.
Point2 held_correction(const MachineCorrection& correction, Point2 p, CompensateReport& report);

class Compensator {
  public:
    Compensator(const MachineCorrection& correction, const JobFrame& frame,
                const CompensateSettings& settings, CompensateReport& report);

    std::string run(std::string_view job);

  private:
    // The job's lines with their numbers in the file: as the program runs them where it uses
    // LinuxCNC's language (O-words, parameters), else as they stand.
    std::vector<std::pair<std::string, long>> job_lines(std::string_view job);
    CompensateError fail(const std::string& why) const {
        return CompensateError("line " + std::to_string(line_number_) + ": " + why);
    }

    // A point in the job's frame and units as the machine's, and back.
    Point2 offset_or_fail(const char* doing) const;
    Point2 machine_of(Point2 job, Point2 offset) const {
        return {job.x * m_.unit_mm + offset.x, job.y * m_.unit_mm + offset.y};
    }
    Point2 job_of(Point2 machine, Point2 offset) const {
        return {(machine.x - offset.x) / m_.unit_mm, (machine.y - offset.y) / m_.unit_mm};
    }

    // Whatever changes the job's frame (units, work system, offsets) keeps the written
    // position where it is on the machine.
    template <typename Change>
    void reframe(const Change& change) {
        const auto before = m_.offset_mm();
        const Point2 at = before ? machine_of(m_.written_xy, *before) : Point2{};
        change();
        if (const auto after = m_.offset_mm(); before && after) m_.written_xy = job_of(at, *after);
    }

    // Where the point the job means lies on the machine once the job is placed turned (itself
    // when it is not).
    Point2 placed(Point2 p) const;
    void refuse_when_turned(const std::string& what) const;

    void inside_travel(Point2 unplaced, Point2 offset) const;

    Point2 corrected(Point2 p) { return held_correction(correction_, placed(p), report_); }

    void emit(const std::string& text);
    void verbatim(std::string_view raw);

    // The end of an XY move on the machine: X Y words (or polar words) in the job's frame.
    Point2 end_of(const gcode::Line& line, const Polar& polar, Point2 offset) const;

    // X Y of a corrected machine point as the job writes them (absolute, or relative to what
    // was written last), the written position moved on.
    std::string xy_words(Point2 corrected_mm, Point2 offset, int decimals);
    int decimals() const { return m_.unit_mm > 1 ? 5 : 4; }  // a tenth of a micron either way

    void work_offsets(const gcode::Line& line);

    // The G words of a line that set the controller's state (not motion); `not_a_move` when
    // the line's axis words are not a move.
    void state_words(const gcode::Line& line, const std::vector<Code>& codes, bool& not_a_move,
                     std::vector<Code>& kept_codes);
    // The codes that set a mode (units, distance, plane, feed, retract, work system): false for
    // any other.
    bool mode_word(Code c);
    // The codes that set an offset or take the line's axis words for themselves (G10, G52, G92,
    // G28, G53, G4, G38).
    void offset_word(const gcode::Line& line, Code c, bool& not_a_move);
    // G92.1 and G92.2 (the offset cleared), G92.3 (the one saved restored); another G92.x is
    // refused.
    void g92_cleared_or_restored(Code c);
    void g52_local_offset(const gcode::Line& line);
    void g92_sets_offset(const gcode::Line& line);

    // The line's words as its controller reads them: on LinuxCNC and grbl blanks count for
    // nothing and only the controller's letters are words; LinuxCNC's and printers' polar words
    // ('@', '^') taken out first.
    // LinuxCNC stops on a '(' inside a '(' comment ("Nested comment found"); grbl reads the
    // comment to its first ')'. A ';' comment holds anything.
    static void refuse_nested_comment(std::string_view raw);

    std::string words_of(const std::string& raw, Polar* polar = nullptr,
                         std::string_view more_letters = {}) const;

    // What LinuxCNC's interpreter and grbl refuse in a line whose words are all theirs: a letter
    // twice, two codes of one modal group, axis words with no motion to take them, and words
    // that no code on the line (or the motion in force) uses. `m_` holds the line's motion and
    // the F in force.
    // The rules a line's words keep whatever the controller holds: codes it has, one word per
    // letter, one code per modal group.
    void word_rules(const gcode::Line& line, const std::vector<Code>& codes) const;
    // An M word's number: whole, and one the controller has.
    void check_m_word(double value) const;
    // One word per letter (but G and M), one G code per modal group.
    void refuse_repeated_words(const gcode::Line& line, const std::vector<Code>& codes) const;

    void cnc_rules(const gcode::Line& line, const std::vector<Code>& codes, bool polar) const;
    // Words no code on the line (nor `motion`, the motion that takes its axis words, -1 for
    // none) uses, and an arc's word off its plane.
    void unused_words(const gcode::Line& line, const std::vector<Code>& codes, int motion) const;
    // The centre word across the arc's plane (K in G17's, J in G18's, I in G19's).
    void refuse_off_plane_arc_word(const gcode::Line& line) const;

    // Words whose value cannot be below 0: LinuxCNC's "Negative f word used", "Negative spindle
    // speed used", "Negative l word used", an H or D naming no tool; grbl's error 4 ("Negative
    // value received for an expected positive value") for F, P and S.
    void negative_words(const gcode::Line& line) const;

    void line(const std::string& raw);
    // The line's words (its polar words taken into `polar`) and its G codes; throws the
    // compensator's refusal for a line that does not read.
    gcode::Line read_line(const std::string& raw, Polar& polar, std::vector<Code>& codes) const;
    // A move at a feed (`feeds`: a cycle, or a move but G0) under G95 with the spindle at rest.
    void refuse_feed_per_rev_at_rest(bool feeds) const;
    // The M words the compensator follows (the spindle, the extruder's mode) and the subprogram
    // calls it refuses.
    void spindle_and_extruder_words(const gcode::Line& line);
    // A line that moves neither X nor Y, written as it stands (or as rewritten): a Z or E move
    // (`moves`) and the other axes it drives (`drives_other_axes`) followed.
    void not_an_xy_move(const std::string& raw, const gcode::Line& line, bool moves,
                        bool drives_other_axes);
    // The Z and the extruder's E a move gives, and the other axes (A, B, C, U, V, W) it drives,
    // kept in the modes as the controller keeps them.
    void follow_z_and_extruder(const gcode::Line& line);
    void follow_other_axes(const gcode::Line& line);

    void machine_move(const std::string& raw, const gcode::Line& line);

    void move(const std::string& raw, const gcode::Line& line, const Polar& polar,
              const std::vector<Code>& kept_codes, bool is_arc_mode);
    // A move's pieces: an arc's chords, or a line cut to the longest piece the settings allow.
    std::vector<PathPoint> pieces_of(const gcode::Line& line, bool is_arc_mode, Point2 from,
                                     Point2 to, std::optional<double> z_from,
                                     std::optional<double> z_to) const;
    // The other axes a move of `pieces` pieces drives, from where they are to where it sends
    // them; an axis the file has not placed yet is taken as given when the move is one piece.
    std::vector<OtherAxis> other_axes_driven(const gcode::Line& line, std::size_t pieces);

    std::string z_word(double z_mm);

    // An offset line (G92, G10 L20) with its X and Y words given new values, everything else on
    // it as written.
    std::string offset_line(const gcode::Line& line, Point2 xy) const;

    static std::string other_words(const gcode::Line& line, std::string_view left_out);

    // A canned cycle's block: each hole (L repeats of it) placed through the correction; the
    // cycle kept for LinuxCNC, written out as moves for controllers without cycles.
    void cycle(const std::string& raw, const gcode::Line& line, const Polar& polar,
               const std::vector<Code>& kept_codes);
    // A cycle block's R, Z, Q and P taken into those in force, and the block refused where its
    // controller would stop on it (no R or Z, no dwell, the spindle stopped, drilling upwards).
    void take_cycle_words(const gcode::Line& line);

    // A hole as moves, for a controller without canned cycles (grbl, printers' firmware).
    void written_out_cycle(Point2 c, Point2 offset, double r_mm, double bottom_mm,
                           std::optional<double> clear_mm, const gcode::Line& line,
                           const std::vector<Code>& kept_codes, bool first);
    // G73's and G83's pecks from R down to the bottom, Q at a time (G83 back to R between them).
    void written_out_pecks(double r_mm, double bottom_mm);

    const MachineCorrection& correction_;
    const JobFrame& frame_;
    const CompensateSettings& settings_;
    CompensateReport& report_;
    Modal m_;
    Numbering numbering_;
    std::string out_;
    long line_number_ = 0;
    bool numbered_ = false, checksummed_ = false, machine_move_ = false;
    int motion_before_ = -1;  // the motion in force before the line being read
    // An offset line as the controller must read it, where calbox rewrote it (G92, G10 L20).
    std::optional<std::string> rewritten_;
    double written_precision_ = 1;  // the job's units: 0.001 for a file written to 3 decimals
};

}  // namespace calbox::jobs::compensating
