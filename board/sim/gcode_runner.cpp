#include "board/sim/gcode_runner.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

namespace calbox::sim {
namespace {

// Commands a print or burn job may carry that change nothing the twin models.
bool is_harmless(const gcode::Line& l) {
    static const std::set<std::pair<char, int>> kNoEffect{
        {'G', 4},   {'G', 21},  {'M', 84},  {'M', 18},  {'M', 104}, {'M', 105}, {'M', 106},
        {'M', 107}, {'M', 109}, {'M', 110}, {'M', 114}, {'M', 117}, {'M', 118}, {'M', 140},
        {'M', 190}, {'M', 400}, {'M', 204}, {'M', 220}, {'M', 221}, {'M', 201}, {'M', 203}};
    return kNoEffect.count({l.command_letter, l.command_number}) != 0;
}

std::string format_command(const gcode::Line& l) {
    return std::string(1, l.command_letter) + std::to_string(l.command_number);
}

}  // namespace

GcodeRunner::GcodeRunner(MachineTwin& machine, const ToolSettings& tool)
    : machine_(machine), tool_(tool) {
    if (!(tool.segment_mm > 0)) throw JobError("segment length must be positive");
}

void GcodeRunner::run(std::istream& job) {
    std::string text;
    while (std::getline(job, text)) run_line(text);
}

void GcodeRunner::run_line(std::string_view text) {
    ++line_number_;
    try {
        // A system command ("$#"), numbered and checksummed like any line the host sends.
        std::string_view command = gcode::without_checksum(text);
        if (const auto first = command.find_first_not_of(" \t");
            first != std::string_view::npos && (command[first] == 'N' || command[first] == 'n')) {
            const auto space = command.find(' ', first);
            command = space == std::string_view::npos ? std::string_view() : command.substr(space);
        }
        if (const auto first = command.find_first_not_of(" \t");
            first != std::string_view::npos && command[first] == '$') {
            command = command.substr(first);
            while (!command.empty() && (command.back() == '\r' || command.back() == ' '))
                command.remove_suffix(1);
            auto reply = machine_.system_command(command);
            if (!reply)
                throw JobError("line " + std::to_string(line_number_) + ": unknown command " +
                               std::string(command));
            for (auto& r : *reply)
                if (r != "ok") result_.replies.push_back(std::move(r));
            ++result_.lines_run;
            return;
        }
        const gcode::Line line = gcode::parse_line(text);
        if (line.command_letter != 0) execute(line);
        ++result_.lines_run;
    } catch (const gcode::SyntaxError& e) {
        throw JobError("line " + std::to_string(line_number_) + ": " + e.what());
    } catch (const OutOfReach& e) {
        throw JobMachineError("line " + std::to_string(line_number_) + ": " + e.what());
    } catch (const ProbeAlarm& e) {
        throw JobMachineError("line " + std::to_string(line_number_) + ": " + e.what(), e.alarm);
    } catch (const MachineError& e) {
        throw JobMachineError("line " + std::to_string(line_number_) + ": " + e.what());
    }
}

void GcodeRunner::execute(const gcode::Line& l) {
    if (l.is('G', 0) || l.is('G', 1)) return move(l);
    if (l.is('G', 53)) return move_in_machine_coordinates(l);
    if (l.command_letter == 'G' && l.command_number == 38 && l.command_subcode == 2)
        return probe(l);
    if (l.is('G', 28)) {
        machine_.home();
        offset_ = {};
        logical_ = machine_.position_after_homing_mm();
        tool_on_ = false;
        return;
    }
    if (l.is('G', 30)) {
        if (tool_on_)
            throw JobError("line " + std::to_string(line_number_) + ": G30 with the tool on");
        Vec3 at = logical_ + offset_;
        if (const auto x = l.value('X')) at.x = *x + offset_.x;
        if (const auto y = l.value('Y')) at.y = *y + offset_.y;
        for (auto& r : machine_.probe_bed(l, at)) result_.replies.push_back(std::move(r));
        logical_ = at - offset_;
        return;
    }
    if (l.is('G', 90)) {
        absolute_xyz_ = true;
        absolute_e_ = true;
        return;
    }
    if (l.is('G', 91)) {
        absolute_xyz_ = false;
        absolute_e_ = false;
        return;
    }
    if (l.is('M', 82)) {
        absolute_e_ = true;
        return;
    }
    if (l.is('M', 83)) {
        absolute_e_ = false;
        return;
    }
    if (l.is('G', 92)) {
        const bool none = l.parameters.empty();
        const Vec3 machine_pos = logical_ + offset_;
        if (none || l.has('X')) logical_.x = l.value('X').value_or(0);
        if (none || l.has('Y')) logical_.y = l.value('Y').value_or(0);
        if (none || l.has('Z')) logical_.z = l.value('Z').value_or(0);
        if (none || l.has('E')) e_ = l.value('E').value_or(0);
        offset_ = machine_pos - logical_;
        return;
    }
    if (l.is('G', 20))
        throw JobError("line " + std::to_string(line_number_) +
                       ": G20 (inches) is not supported; use millimetres (G21)");
    if (tool_.kind != ToolKind::extruder && (l.is('M', 3) || l.is('M', 4))) {
        tool_on_ = l.value('S').value_or(1.0) > 0;
        return;
    }
    if (tool_.kind != ToolKind::extruder && l.is('M', 5)) {
        tool_on_ = false;
        return;
    }
    if (auto reply = machine_.settings_command(l)) {
        for (auto& r : *reply) result_.replies.push_back(std::move(r));
        return;
    }
    if (is_harmless(l)) return;
    throw JobError("line " + std::to_string(line_number_) + ": unknown command " +
                   format_command(l));
}

void GcodeRunner::move_in_machine_coordinates(const gcode::Line& l) {
    const auto motion = l.value('G');
    if (motion != 0.0 && motion != 1.0)
        throw JobError("line " + std::to_string(line_number_) + ": G53 with G0 or G1 only");
    // The same move in the job's coordinates, absolute whatever the job's mode.
    const Vec3 zero = machine_.work_zero_mm() + offset_;
    gcode::Line in_job;
    in_job.command_letter = 'G';
    in_job.command_number = static_cast<int>(*motion);
    for (const auto& [letter, field] :
         {std::pair{'X', zero.x}, std::pair{'Y', zero.y}, std::pair{'Z', zero.z}})
        if (const auto v = l.value(letter)) in_job.parameters.push_back({letter, *v - field, {}});
    const bool absolute = absolute_xyz_;
    absolute_xyz_ = true;
    move(in_job);
    absolute_xyz_ = absolute;
}

void GcodeRunner::probe(const gcode::Line& l) {
    const auto z = l.value('Z');
    if (!z || l.has('X') || l.has('Y'))
        throw JobError("line " + std::to_string(line_number_) +
                       ": the twin's probe goes straight down: G38.2 Z alone");
    const double to_z = absolute_xyz_ ? *z : logical_.z + *z;
    if (!(to_z < logical_.z))
        throw JobError("line " + std::to_string(line_number_) + ": G38.2 upwards");
    const Vec3 touched = machine_.probe_down(logical_ + offset_, to_z + offset_.z);
    logical_ = touched - offset_;
    const Vec3 reported = touched + machine_.work_zero_mm();
    char line[96];
    std::snprintf(line, sizeof line, "[PRB:%.3f,%.3f,%.3f:1]", reported.x, reported.y, reported.z);
    result_.replies.emplace_back(line);
}

StrandShape first_layer_strand(double cross_section_mm2, double gap_mm, double nozzle_flat_mm) {
    if (!(cross_section_mm2 > 0) || !(nozzle_flat_mm > 0))
        throw std::invalid_argument("a strand needs a cross-section and a nozzle");
    const double bead_mm = std::sqrt(4 * cross_section_mm2 / 3.14159265358979323846);
    // A scraped trace still has some height: the bed's texture and the nozzle's own wear.
    constexpr double kScrapedTraceMm = 0.01;
    StrandShape s;
    s.free_bead = gap_mm >= bead_mm;
    s.height_mm = std::clamp(gap_mm, kScrapedTraceMm, bead_mm);
    s.width_mm = std::min(cross_section_mm2 / s.height_mm, nozzle_flat_mm);
    return s;
}

void GcodeRunner::move(const gcode::Line& l) {
    Vec3 target = logical_;
    double e_target = e_;
    const auto axis = [&](char letter, double& field) {
        if (const auto v = l.value(letter)) {
            if (!std::isfinite(*v))
                throw JobError("line " + std::to_string(line_number_) + ": non-finite " + letter);
            field = absolute_xyz_ ? *v : field + *v;
        } else if (l.has(letter)) {
            throw JobError("line " + std::to_string(line_number_) + ": " + letter +
                           " without a value");
        }
    };
    axis('X', target.x);
    axis('Y', target.y);
    axis('Z', target.z);
    if (const auto e = l.value('E')) e_target = absolute_e_ ? *e : e_ + *e;
    const double extruded = e_target - e_;
    const Vec3 from = logical_ + offset_, to = target + offset_;
    const double length = (to - from).norm();
    const bool marks =
        tool_.kind == ToolKind::extruder ? extruded > 0 && length > 0 : tool_on_ && length > 0;
    const int segments = std::max(1, static_cast<int>(std::ceil(length / tool_.segment_mm)));
    const double filament_area =
        3.14159265358979323846 * tool_.filament_diameter_mm * tool_.filament_diameter_mm / 4.0;
    Vec3 previous_commanded = from;
    Vec3 previous_actual = machine_.actual_position_mm(from);
    for (int k = 1; k <= segments; ++k) {
        const Vec3 commanded = from + (to - from) * (static_cast<double>(k) / segments);
        const Vec3 actual = machine_.actual_position_mm(commanded);
        // A cutter marks only below the surface: a plunge from above cuts from where it enters.
        const bool cuts =
            tool_.kind != ToolKind::spindle || std::max(previous_commanded.z, commanded.z) <= 1e-9;
        if (marks && cuts) {
            Stroke s{previous_commanded,  commanded,    previous_actual,   actual,
                     tool_.tool_width_mm, line_number_, previous_actual.z, actual.z};
            if (tool_.kind == ToolKind::extruder) {
                // The segment's share of the filament spreads over its true length.
                const double volume = extruded / segments * filament_area;
                const double true_length =
                    std::hypot(actual.x - previous_actual.x, actual.y - previous_actual.y);
                const double cross_section = true_length > 0 ? volume / true_length : 0;
                s.width_mm = cross_section / tool_.layer_height_mm;
                // Only the first layer lies on the bed; later ones sit on the layer below. Which
                // layer a stroke is the job says: a badly levelled bed's gap under the first one
                // can be more than a layer and a half.
                const double gap = (previous_actual.z + actual.z) / 2;
                const double commanded_z = (previous_commanded.z + commanded.z) / 2;
                if (tool_.real_first_layer && cross_section > 0 &&
                    commanded_z < 1.5 * tool_.layer_height_mm) {
                    const auto at = [&](double nozzle_z) {
                        return first_layer_strand(cross_section, nozzle_z, tool_.nozzle_flat_mm);
                    };
                    s.width_mm = at(gap).width_mm;
                    s.top_a_mm = at(previous_actual.z).height_mm;
                    s.top_b_mm = at(actual.z).height_mm;
                }
            }
            if (s.width_mm > 0) result_.strokes.push_back(s);
        }
        previous_commanded = commanded;
        previous_actual = actual;
    }
    logical_ = target;
    e_ = e_target;
}

}  // namespace calbox::sim
