#include "core/modes/compensate_job.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>

#include "core/models/machine_file.hpp"
#include "core/modes/galvo.hpp"
#include "core/modes/json_file.hpp"
#include "core/modes/planar.hpp"
#include "core/modes/registration.hpp"
#include "core/modes/stock.hpp"
#include "core/number_text.hpp"

namespace calbox::modes {
namespace {

using geometry::Point2;

constexpr const char* kSystemNames[jobs::kWorkSystems] = {"G54", "G55",   "G56",   "G57",  "G58",
                                                          "G59", "G59.1", "G59.2", "G59.3"};

std::string mm(double v) {
    return number_text("%.3f", v);
}

std::optional<Point2> pair_of(std::string_view text) {
    const auto comma = text.find(',');
    if (comma == std::string_view::npos) return std::nullopt;
    const auto number_in = [](std::string_view s) -> std::optional<double> {
        if (!s.empty() && s.front() == '+') s.remove_prefix(1);
        double v = 0;
        const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
        if (s.empty() || ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v))
            return std::nullopt;
        return v;
    };
    const auto x = number_in(text.substr(0, comma)), y = number_in(text.substr(comma + 1));
    if (!x || !y) return std::nullopt;
    return Point2{*x, *y};
}

std::string schema_of(const std::string& text, const std::string& name) {
    // What the box keeps when no correction is in force (never one, or reverted).
    if (text == "none\n" || text == "none")
        throw JobError(name +
                       ": no correction in force (the box keeps none: reverted, or never "
                       "calibrated)");
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception&) {
        throw JobError(name + ": not a result file (malformed JSON)");
    }
    if (!j.is_object() || !j.contains("schema") || !j["schema"].is_string())
        throw JobError(name + ": not a result file (no schema)");
    return j["schema"].get<std::string>();
}

}  // namespace

std::array<std::optional<Point2>, jobs::kWorkSystems> parse_work_zero(const std::string& spec,
                                                                      Point2 measured_mm) {
    std::array<std::optional<Point2>, jobs::kWorkSystems> zeros{};
    const auto bad = [&](const std::string& what) {
        return JobError("--work-zero '" + spec + "': " + what +
                        "; give X,Y (G54's zero in machine coordinates), 'measured', or "
                        "G54=X,Y G55=X,Y ...");
    };
    std::istringstream in(spec);
    std::string entry;
    int entries = 0;
    while (in >> entry) {
        ++entries;
        std::size_t system = 0;
        std::string value = entry;
        if (const auto eq = entry.find('='); eq != std::string::npos) {
            std::string name = entry.substr(0, eq);
            for (auto& c : name) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
            system = jobs::kWorkSystems;
            for (std::size_t k = 0; k < jobs::kWorkSystems; ++k)
                if (name == kSystemNames[k]) system = k;
            if (system == jobs::kWorkSystems) throw bad("'" + name + "' is no work system");
            value = entry.substr(eq + 1);
        }
        if (zeros[system]) throw bad(std::string(kSystemNames[system]) + " given twice");
        if (value == "measured") {
            zeros[system] = measured_mm;
        } else if (const auto p = pair_of(value)) {
            zeros[system] = *p;
        } else {
            throw bad("'" + value + "' is not X,Y in millimetres");
        }
    }
    if (entries == 0) throw bad("nothing given");
    return zeros;
}

namespace {

// The job placed where its drawing's printed marks were found (--register).
std::string registered_zero(const JobRequest& r, const PlanarSolution& planar,
                            jobs::JobFrame& frame) {
    const auto found = registration_from_json(*r.registration_text, *r.registration_name);
    if (found.machine_fingerprint != planar.machine_fingerprint)
        throw JobError(
            *r.registration_name + ": the marks were found through the result of machine " +
            found.machine_fingerprint + ", not " + r.result_name + "'s (" +
            planar.machine_fingerprint + "): find them again through the result in force");
    const auto& g = found.registration;
    frame.work_zero_mm = {g.origin_mm};
    frame.turn_rad = g.rotation_deg * std::numbers::pi / 180;
    frame.scale = g.scale;
    return "the printed marks: " + *r.registration_name + "'s " + std::to_string(g.marks.size()) +
           " marks, the drawing's zero at machine X" + mm(g.origin_mm.x) + " Y" +
           mm(g.origin_mm.y) + " mm turned " + number_text("%.3f", g.rotation_deg) + " deg" +
           (g.scale_fitted ? ", scaled " + number_text("%.5f", g.scale) : "") + " (worst mark " +
           number_text("%.3f", g.worst_residual_mm) + " mm)";
}

// The job placed at a corner of the sheet the camera found (--work-zero camera), turned with it.
std::string camera_zero(const JobRequest& r, const PlanarSolution& planar, jobs::JobFrame& frame) {
    const auto found = stock_from_json(*r.stock_text, *r.stock_name);
    if (found.machine_fingerprint != planar.machine_fingerprint)
        throw JobError(*r.stock_name +
                       ": the sheet was found through the result of "
                       "machine " +
                       found.machine_fingerprint + ", not " + r.result_name + "'s (" +
                       planar.machine_fingerprint + "): find it again through the result in force");
    const StockCorner* corner = nullptr;
    try {
        corner = &modes::stock_corner(found.stock, r.stock_corner);
    } catch (const StockError& e) {
        throw JobError("--corner " + std::string(e.what()));
    }
    frame.work_zero_mm = {corner->machine_mm};
    frame.turn_rad = found.stock.rotation_deg * std::numbers::pi / 180;
    return "the camera: " + *r.stock_name + "'s " + corner->name + " corner at machine X" +
           mm(corner->machine_mm.x) + " Y" + mm(corner->machine_mm.y) + " mm (+/-" +
           number_text("%.3f", corner->sigma_mm) + "), the job turned " +
           number_text("%.3f", found.stock.rotation_deg) + " deg with the sheet's front edge";
}

// Where a router's, laser's or printer's job lies on the machine: what says so, in words.
std::string planar_job_zero(const JobRequest& r, const PlanarSolution& planar, Point2 zm,
                            jobs::JobFrame& frame) {
    const auto& f = *planar.frame;
    std::string zero_from;
    if (frame.flavour == jobs::Flavour::printer) {
        if (r.work_zero || r.stock_text || r.registration_text)
            throw JobError(r.job_name +
                           ": a printer's job is in machine coordinates (its G92 tracked); "
                           "--work-zero, --stock and --register are for routers and lasers");
        frame.work_zero_mm = {Point2{}};
        zero_from = "machine coordinates (a printer's job, G92 tracked)";
    } else if (r.registration_text) {
        if (r.work_zero || r.stock_text)
            throw JobError(
                "--register places the job where its drawing lies: give neither "
                "--work-zero nor --stock with it");
        zero_from = registered_zero(r, planar, frame);
    } else {
        if (!r.work_zero)
            throw JobError(r.job_name + ": a " + f.kind +
                           "'s job is written around its work zero, which calbox cannot see: "
                           "give --work-zero X,Y (the machine coordinates of the job's G54 "
                           "zero), or --work-zero measured (the frame the result was "
                           "measured in: zero at machine X" +
                           mm(zm.x) + " Y" + mm(zm.y) + ")");
        if (*r.work_zero == "camera") {
            if (!r.stock_text)
                throw JobError(
                    "--work-zero camera places the job at the sheet the camera "
                    "found: give --stock stock.json (calbox view stock)");
            zero_from = camera_zero(r, planar, frame);
        } else {
            if (r.stock_text)
                throw JobError("--stock is for --work-zero camera, not --work-zero " +
                               *r.work_zero);
            frame.work_zero_mm = parse_work_zero(*r.work_zero, zm);
            zero_from = r.work_zero_from.empty() ? "--work-zero " + *r.work_zero : r.work_zero_from;
        }
    }
    return zero_from;
}

// A planar result's correction and the job's frame from it.
void planar_correction(const JobRequest& r, jobs::MachineCorrection& correction,
                       jobs::JobFrame& frame, CompensatedJob& done) {
    const PlanarSolution planar = planar_result_from_json(r.result_text, r.result_name);
    if (!planar.frame)
        throw JobError(r.result_name +
                       ": a result from before calbox recorded the frame it was measured in "
                       "(work zero, travel): solve the measurements again");
    const auto& f = *planar.frame;
    const Point2 zm = f.work_zero_mm;
    correction.correct = [solution = planar, zm](Point2 p) {
        const Point2 c = planar_command_for(solution, {p.x - zm.x, p.y - zm.y});
        return Point2{c.x + zm.x, c.y + zm.y};
    };
    correction.measured_mm = {planar.min_x_mm + zm.x, planar.min_y_mm + zm.y,
                              planar.max_x_mm + zm.x, planar.max_y_mm + zm.y};
    frame.travel_mm = {f.travel_min_x_mm, f.travel_min_y_mm, f.travel_max_x_mm, f.travel_max_y_mm};
    frame.flavour = jobs::flavour_of_firmware(f.firmware);
    const std::string zero_from = planar_job_zero(r, planar, zm, frame);
    done.frame_line = "frame: job placed with " + zero_from;
    // A printer's job is in machine coordinates: no work zero to name.
    if (frame.work_zero_mm[0] && frame.flavour != jobs::Flavour::printer)
        done.frame_line += " (G54 zero at machine X" + mm(frame.work_zero_mm[0]->x) + " Y" +
                           mm(frame.work_zero_mm[0]->y) + " mm)";
    done.frame_line +=
        "; the result measured with its zero at machine X" + mm(zm.x) + " Y" + mm(zm.y) +
        " mm (from " + f.work_zero_from + "), over X " + mm(correction.measured_mm.min_x_mm) +
        ".." + mm(correction.measured_mm.max_x_mm) + " Y " + mm(correction.measured_mm.min_y_mm) +
        ".." + mm(correction.measured_mm.max_y_mm) + " mm; travel X " + mm(f.travel_min_x_mm) +
        ".." + mm(f.travel_max_x_mm) + " Y " + mm(f.travel_min_y_mm) + ".." +
        mm(f.travel_max_y_mm) + " mm";
}

// A galvo result's correction: the job in the scanner's field coordinates.
void galvo_correction(const JobRequest& r, jobs::MachineCorrection& correction,
                      jobs::JobFrame& frame, CompensatedJob& done) {
    if (r.stock_text || r.registration_text || (r.work_zero && *r.work_zero == "camera"))
        throw JobError(r.result_name +
                       ": a scanner's job is in its field's coordinates; --work-zero camera "
                       "places a router's or laser's job on the sheet a planar result sees");
    const GalvoSolution galvo = galvo_result_from_json(r.result_text, r.result_name);
    const auto table = galvo.fit.table;
    correction.correct = [table](Point2 p) { return table.command_for(p); };
    correction.measured_mm = {table.min_x_mm, table.min_y_mm, table.max_x_mm, table.max_y_mm};
    // A scanner's job is in its field's coordinates, the machine's own; the field is its
    // travel.
    frame.flavour = jobs::Flavour::grbl;
    frame.work_zero_mm = {Point2{}};
    if (galvo.field_size_mm) {
        const double half = *galvo.field_size_mm / 2;
        frame.travel_mm = {-half, -half, half, half};
    }
    if (r.work_zero) frame.work_zero_mm = parse_work_zero(*r.work_zero, Point2{});
    done.frame_line = "frame: the scanner's field coordinates" +
                      (r.work_zero ? " moved by --work-zero " + *r.work_zero : std::string()) +
                      "; the table over X " + mm(table.min_x_mm) + ".." + mm(table.max_x_mm) +
                      " Y " + mm(table.min_y_mm) + ".." + mm(table.max_y_mm) + " mm";
}

// Where the tool stands when the job starts (--start-at), inside the travel.
void start_at(const JobRequest& r, jobs::JobFrame& frame, CompensatedJob& done) {
    if (r.start_at) {
        const auto start = pair_of(*r.start_at);
        if (!start)
            throw JobError("--start-at '" + *r.start_at +
                           "': not X,Y in millimetres (where the tool stands when the job starts, "
                           "machine coordinates)");
        if (!frame.travel_mm.contains(*start))
            throw JobError("--start-at " + *r.start_at + ": beyond the machine's travel");
        frame.start_mm = start;
        done.frame_line += "; the tool starts at machine X" + mm(start->x) + " Y" + mm(start->y) +
                           " mm (--start-at)";
    }
}

}  // namespace

CompensatedJob compensate_job(const JobRequest& r) {
    if (const auto mark = jobs::compensated_mark_in(r.job_text); !mark.empty() && !r.again_because)
        throw JobError(r.job_name + ": already compensated (its line '" + mark +
                       "'): compensating it again would correct twice; give --again REASON if "
                       "that is meant");
    const std::string schema = schema_of(r.result_text, r.result_name);
    jobs::MachineCorrection correction;
    jobs::JobFrame frame;
    CompensatedJob done;
    if (schema.rfind("calbox.planar-result/", 0) == 0) {
        planar_correction(r, correction, frame, done);
    } else if (schema.rfind("calbox.galvo-result/", 0) == 0) {
        galvo_correction(r, correction, frame, done);
    } else {
        throw JobError(r.result_name + ": not a planar or galvo result (schema " + schema + ")");
    }
    start_at(r, frame, done);
    done.report.keep_path = r.keep_path;
    try {
        const bool scanner = r.job_text.rfind("x_mm,y_mm,power", 0) == 0;
        const std::string compensated =
            scanner
                ? jobs::compensate_scanner_csv(r.job_text, correction, frame, r.settings,
                                               done.report)
                : jobs::compensate_gcode(r.job_text, correction, frame, r.settings, done.report);
        std::string mark = jobs::compensated_mark(models::digest(r.result_text), r.date);
        if (r.again_because) mark += " (again: " + *r.again_because + ")";
        done.text = jobs::with_compensated_mark(compensated, mark);
    } catch (const jobs::CompensateError& e) {
        throw JobError(r.job_name + ": " + e.what());
    }
    const auto& rep = done.report;
    done.summary = std::to_string(rep.lines) + " lines" +
                   (rep.ran_program ? " (LinuxCNC's program evaluated)" : std::string()) + ", " +
                   std::to_string(rep.moves) + " moves corrected as " + std::to_string(rep.pieces) +
                   " pieces, " + std::to_string(rep.arcs) + " arcs traced, " +
                   std::to_string(rep.holes) + " holes placed";
    if (rep.held > 0)
        done.held_line = std::to_string(rep.held) + " points lie beyond the measured area, up to " +
                         number_text("%.1f", rep.held_farthest_mm) +
                         " mm: each took the correction at the area's nearest edge (held, not "
                         "extrapolated)";
    return done;
}

}  // namespace calbox::modes
