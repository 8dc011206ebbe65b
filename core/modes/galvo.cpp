#include "core/modes/galvo.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>

#include "core/modes/json_file.hpp"
#include "core/modes/mark_grid.hpp"
#include "core/modes/mark_records.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {
namespace {

using geometry::Point2;
using targets::GridIndex;

// The spot finder set for the scanner's marks: their polarity and size, and the field's outline
// in the photo (within its diagonal of the plane's board, which lay on the platform).
vision::SpotSettings galvo_spot_settings(const models::MachineFile& machine,
                                         const geometry::CameraModel& camera,
                                         const geometry::BedPlane& plane, double pitch,
                                         const GalvoMeasureSettings& settings) {
    vision::SpotSettings spots = settings.spots;
    spots.polarity =
        machine.galvo->marks == "light" ? vision::MarkPolarity::light : vision::MarkPolarity::dark;
    spots.mark_diameter_px =
        0.8 * pitch * pixels_per_mm_at_centre(camera, plane, machine.galvo->substrate_height_mm);
    spots.search_outline_px =
        work_outline_px(camera, plane, machine.galvo->substrate_height_mm,
                        std::sqrt(2.0) * machine.galvo->field_size_mm + kOutlineMarginMm);
    return spots;
}

// Which of the square's eight symmetries carries the photo's grid onto the target's: the one
// under which the large marks seen fall on the target's large marks; refused when the large
// marks do not settle it.
int grid_symmetry(const Lattice& lattice, const std::vector<MarkCandidate>& candidates, int min_a,
                  int min_b, int n) {
    std::array<int, 8> mismatches{};
    for (int g = 0; g < 8; ++g)
        for (const auto& [index, node] : lattice) {
            if (node.candidate < 0) continue;
            const GridIndex t =
                targets::apply_symmetry(g, {index.first - min_a, index.second - min_b}, n);
            if (candidates[static_cast<std::size_t>(node.candidate)].large !=
                targets::is_large_mark(t, n))
                ++mismatches[static_cast<std::size_t>(g)];
        }
    std::array<int, 8> order{0, 1, 2, 3, 4, 5, 6, 7};
    std::sort(order.begin(), order.end(), [&](int a, int b) {
        return mismatches[static_cast<std::size_t>(a)] < mismatches[static_cast<std::size_t>(b)];
    });
    const int best = mismatches[static_cast<std::size_t>(order[0])],
              second = mismatches[static_cast<std::size_t>(order[1])];
    if (best > 3 || second < best + 4)
        throw GalvoError("measure: the large marks do not settle which way round the grid lies (" +
                         std::to_string(best) + " marks disagree with the best reading, " +
                         std::to_string(second) +
                         " with the next): not this target, or too many marks damaged");
    return order[0];
}

}  // namespace

GalvoMeasurement measure_galvo(const models::MachineFile& machine,
                               const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               const vision::GrayView& photo,
                               const GalvoMeasureSettings& settings) {
    const auto target = targets::galvo_grid(machine, settings.target);
    const double pitch = target.pitch_mm;
    const int n = target.grid_count;
    if (const auto size = geometry::photo_size_mismatch(camera, photo.width_px, photo.height_px);
        !size.empty())
        throw GalvoError("measure: the photo is " + size);
    const vision::SpotSettings spots = galvo_spot_settings(machine, camera, plane, pitch, settings);
    const vision::SpotImage seen = vision::find_spots(photo, spots);
    GalvoMeasurement out;
    out.machine_fingerprint = models::fingerprint(machine);
    out.target_fingerprint = target.fingerprint;
    out.grid_count = n;
    out.pitch_mm = pitch;
    out.dark_marks = seen.dark_marks;

    std::vector<MarkCandidate> candidates;
    const double small = 0.2 * pitch, large = 0.4 * pitch;
    for (const auto& m : marks_on_bed(camera, plane, seen, machine.galvo->substrate_height_mm)) {
        const bool is_small = m.radius_mm > 0.6 * small && m.radius_mm < 1.4 * small;
        const bool is_large = m.radius_mm > 0.75 * large && m.radius_mm < 1.25 * large;
        if (m.touches_border || m.elongation > settings.max_elongation || !(is_small || is_large)) {
            out.extra_mm.push_back(m.bed_mm);
            continue;
        }
        candidates.push_back({m.bed_mm, m.radius_mm, m.sigma_mm, is_large, false});
    }
    // A mark with spatter fused to it, a chip or a double burn is larger than its kind.
    set_aside_odd_sizes(candidates, settings.max_radius_deviation, out.extra_mm);
    if (candidates.size() < geometry::grid_nodes(n) / 2)
        throw GalvoError("measure: " + std::to_string(candidates.size()) + " marks of the " +
                         std::to_string(n) + " x " + std::to_string(n) +
                         " grid's size in the photo (under half of them): not this target, or the "
                         "photo does not show it");
    Lattice lattice;
    try {
        lattice = grow_lattice(candidates, pitch, settings.match_reach_pitch * pitch);
    } catch (const LatticeError& e) {
        throw GalvoError(e.what());
    }
    const LatticeExtent extent = lattice_extent(lattice);
    const int min_a = extent.min_a, min_b = extent.min_b;
    const int columns = extent.columns(), rows = extent.rows();
    if (columns != n || rows != n)
        throw GalvoError("measure: the grid found is " + std::to_string(columns) + " x " +
                         std::to_string(rows) + " marks, the target's is " + std::to_string(n) +
                         " x " + std::to_string(n) +
                         (columns > n || rows > n
                              ? ": not this target"
                              : ": part of it is outside the photo, or whole rows are missing"));
    out.symmetry = grid_symmetry(lattice, candidates, min_a, min_b, n);
    std::vector<bool> seen_node(geometry::grid_nodes(n), false);
    for (const auto& [index, node] : lattice) {
        if (node.candidate < 0) continue;
        const GridIndex t =
            targets::apply_symmetry(out.symmetry, {index.first - min_a, index.second - min_b}, n);
        const auto& c = candidates[static_cast<std::size_t>(node.candidate)];
        const auto& mark = target.at(t);
        out.nodes.push_back({t, mark.centre_mm, mark.large, c.bed_mm, c.sigma_mm});
        seen_node[geometry::grid_offset(t.column, t.row, n)] = true;
    }
    for (const auto& c : candidates)
        if (!c.taken) out.extra_mm.push_back(c.bed_mm);
    for (const auto& mark : target.marks)
        if (!seen_node[geometry::grid_offset(mark.index.column, mark.index.row, n)])
            out.missing.push_back(mark.index);
    std::sort(out.nodes.begin(), out.nodes.end(), [](const auto& a, const auto& b) {
        return std::make_pair(a.index.row, a.index.column) <
               std::make_pair(b.index.row, b.index.column);
    });
    return out;
}

GalvoSolution solve_galvo(const models::MachineFile& machine, const GalvoMeasurement& measured,
                          const std::optional<GalvoSolution>& burned_through,
                          const GalvoSolveOptions& options) {
    if (!machine.is_galvo() || !machine.galvo)
        throw GalvoError("solve: the machine is a " + machine.kind + ", not a galvo");
    if (measured.machine_fingerprint != models::fingerprint(machine))
        throw GalvoError(
            "solve: the measurements were made for another machine file (fingerprint " +
            measured.machine_fingerprint + ")");
    const auto target = targets::galvo_grid(machine, {measured.grid_count});
    if (measured.target_fingerprint != target.fingerprint)
        throw GalvoError("solve: the measurements are of another target than this machine's " +
                         std::to_string(measured.grid_count) + " x " +
                         std::to_string(measured.grid_count) + " grid");
    if (burned_through && burned_through->machine_fingerprint != measured.machine_fingerprint)
        throw GalvoError("solve: the table the grid was burned through is another machine's");
    const int n = measured.grid_count;
    const models::SquareGrid grid{n, measured.pitch_mm};
    std::vector<std::optional<Point2>> landed(geometry::grid_nodes(n));
    double sigma2 = 0;
    for (const auto& node : measured.nodes) {
        landed[geometry::grid_offset(node.index.column, node.index.row, n)] = node.measured_mm;
        sigma2 += 2 * node.sigma_mm * node.sigma_mm;
    }
    const auto through = burned_through ? burned_through->fit.table
                                        : models::identity_table(machine.galvo->field_size_mm / 2,
                                                                 options.table_nodes);
    GalvoSolution s;
    s.machine_fingerprint = measured.machine_fingerprint;
    s.fit = models::fit_galvo_field(grid, landed, through, options.table_nodes);
    s.pass = burned_through ? burned_through->pass + 1 : 1;
    s.field_size_mm = machine.galvo->field_size_mm;
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) s.intended_mm.push_back(grid.node_mm(c, r));
    s.measurement_sigma_mm =
        std::sqrt(sigma2 / static_cast<double>(std::max<std::size_t>(1, measured.nodes.size())));
    // The table goes through every node as measured, so it carries each node's scatter (the
    // burn's repeatability and the photo's noise) into the next burn, which scatters afresh.
    const double scatter = std::max(s.fit.node_scatter_mm, s.measurement_sigma_mm);
    s.predicted_rms_mm =
        std::sqrt(2 * scatter * scatter + std::pow(s.fit.table_interpolation_rms_mm, 2));
    const double limit = options.max_correction_fraction * machine.galvo->field_size_mm;
    const auto& t = s.fit.table;
    for (int r = 0; r < t.nodes; ++r)
        for (int c = 0; c < t.nodes; ++c) {
            const Point2 q = t.node_mm(c, r),
                         cmd = t.command_mm[geometry::grid_offset(c, r, t.nodes)];
            const double correction = std::hypot(cmd.x - q.x, cmd.y - q.y);
            if (correction > limit)
                throw GalvoError("solve: the correction at X" + number_text("%.2f", q.x) + " Y" +
                                 number_text("%.2f", q.y) + " is " +
                                 number_text("%.3f", correction) + " mm, beyond the " +
                                 number_text("%.2f", limit) +
                                 " mm a scanner plausibly needs (check field_size_mm and the "
                                 "photo); nothing written");
            const double half = machine.galvo->field_size_mm / 2;
            if (std::abs(cmd.x) > half || std::abs(cmd.y) > half)
                throw GalvoError("solve: the table would command X" + number_text("%.3f", cmd.x) +
                                 " Y" + number_text("%.3f", cmd.y) +
                                 ", outside the scanner's field; nothing written");
        }
    return s;
}

// ---------------------------------------------------------------------------------------------
// Files

namespace {

using nlohmann::json;

constexpr const char* kGalvoMeasurementsSchema = "calbox.galvo-measurements/1";
constexpr const char* kGalvoResultSchema = "calbox.galvo-result/1";

}  // namespace

std::string galvo_measurements_to_json(const GalvoMeasurement& m) {
    json nodes = json::array();
    for (const auto& node : m.nodes)
        nodes.push_back(mark_json(node, &GalvoNodeMeasurement::intended_mm, "intended_mm"));
    const json j{{"schema", kGalvoMeasurementsSchema},
                 {"machine_fingerprint", m.machine_fingerprint},
                 {"target_fingerprint", m.target_fingerprint},
                 {"photos", m.photos},
                 {"grid_count", m.grid_count},
                 {"pitch_mm", m.pitch_mm},
                 {"symmetry", m.symmetry},
                 {"dark_marks", m.dark_marks},
                 {"nodes", nodes},
                 {"missing", nodes_json(m.missing)},
                 {"extra_mm", points_json(m.extra_mm)}};
    return j.dump(1) + "\n";
}

GalvoMeasurement galvo_measurements_from_json(const std::string& text, const std::string& source) {
    const json j = parse_record(text, source, kGalvoMeasurementsSchema, "galvo measurements");
    try {
        GalvoMeasurement m;
        m.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        m.target_fingerprint = j.at("target_fingerprint").get<std::string>();
        m.photos = j.at("photos").get<std::vector<std::string>>();
        m.grid_count = j.at("grid_count").get<int>();
        m.pitch_mm = j.at("pitch_mm").get<double>();
        m.symmetry = j.at("symmetry").get<int>();
        m.dark_marks = j.at("dark_marks").get<bool>();
        if (m.grid_count < 7 || m.grid_count > 101 || !(m.pitch_mm > 0))
            throw RecordError(source + ": grid_count must be 7 to 101 and pitch_mm positive");
        for (const auto& node : j.at("nodes"))
            m.nodes.push_back(mark_from(node, &GalvoNodeMeasurement::intended_mm, "intended_mm",
                                        m.grid_count, m.grid_count, source, "node"));
        m.missing = nodes_from(j.at("missing"));
        m.extra_mm = points_from(j.at("extra_mm"));
        return m;
    } catch (const json::exception& e) {
        throw RecordError(source + ": " + e.what());
    }
}

std::string galvo_result_to_json(const GalvoSolution& s) {
    const auto& t = s.fit.table;
    json filled = json::array();
    for (std::size_t i = 0; i < s.fit.filled.size(); ++i)
        if (s.fit.filled[i]) filled.push_back(i);
    const json j{{"schema", kGalvoResultSchema},
                 {"machine_fingerprint", s.machine_fingerprint},
                 {"pass", s.pass},
                 {"field_size_mm", s.field_size_mm ? json(*s.field_size_mm) : json(nullptr)},
                 {"before", statistics_json(s.fit.before)},
                 {"measurement_sigma_mm", s.measurement_sigma_mm},
                 {"predicted_rms_mm", s.predicted_rms_mm},
                 {"table_interpolation_max_mm", s.fit.table_interpolation_max_mm},
                 {"table_interpolation_rms_mm", s.fit.table_interpolation_rms_mm},
                 {"intended_mm", points_json(s.intended_mm)},
                 {"landed_mm", points_json(s.fit.landed_mm)},
                 {"filled_nodes", filled},
                 {"table",
                  {{"nodes", t.nodes},
                   {"min_x_mm", t.min_x_mm},
                   {"min_y_mm", t.min_y_mm},
                   {"max_x_mm", t.max_x_mm},
                   {"max_y_mm", t.max_y_mm},
                   {"command_mm", points_json(t.command_mm)}}}};
    return j.dump(1) + "\n";
}

GalvoSolution galvo_result_from_json(const std::string& text, const std::string& source) {
    const json j = parse_record(text, source, kGalvoResultSchema, "galvo result");
    try {
        GalvoSolution s;
        s.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        s.pass = j.at("pass").get<int>();
        if (j.contains("field_size_mm") && !j.at("field_size_mm").is_null()) {
            s.field_size_mm = j.at("field_size_mm").get<double>();
            if (!(*s.field_size_mm > 0))
                throw RecordError(source + ": field_size_mm must be above 0");
        }
        s.fit.before = error_statistics_from(j.at("before"));
        s.measurement_sigma_mm = j.at("measurement_sigma_mm").get<double>();
        s.predicted_rms_mm = j.at("predicted_rms_mm").get<double>();
        s.fit.table_interpolation_max_mm = j.at("table_interpolation_max_mm").get<double>();
        s.fit.table_interpolation_rms_mm = j.at("table_interpolation_rms_mm").get<double>();
        s.intended_mm = points_from(j.at("intended_mm"));
        s.fit.landed_mm = points_from(j.at("landed_mm"));
        s.fit.filled.assign(s.fit.landed_mm.size(), false);
        for (const auto& i : j.at("filled_nodes")) s.fit.filled.at(i.get<std::size_t>()) = true;
        const json& t = j.at("table");
        auto& table = s.fit.table;
        table.nodes = t.at("nodes").get<int>();
        table.min_x_mm = t.at("min_x_mm").get<double>();
        table.min_y_mm = t.at("min_y_mm").get<double>();
        table.max_x_mm = t.at("max_x_mm").get<double>();
        table.max_y_mm = t.at("max_y_mm").get<double>();
        table.command_mm = points_from(t.at("command_mm"));
        if (table.nodes < 2 || table.command_mm.size() != geometry::grid_nodes(table.nodes) ||
            !(table.max_x_mm > table.min_x_mm && table.max_y_mm > table.min_y_mm))
            throw RecordError(source +
                              ": the table is not a square grid of commands over a rectangle");
        return s;
    } catch (const json::exception& e) {
        throw RecordError(source + ": " + e.what());
    } catch (const std::out_of_range& e) {
        throw RecordError(source + ": filled_nodes names a node the grid does not have");
    }
}

}  // namespace calbox::modes
