#include "board/sim/twin_kind.hpp"

#include <array>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <set>
#include <string_view>

#include "board/sim/delta_judge.hpp"
#include "board/sim/galvo_twin.hpp"
#include "board/sim/router_twin.hpp"
#include "board/sim/truth_table.hpp"
#include "board/sim/twin_judge.hpp"
#include "core/modes/delta_records.hpp"
#include "core/modes/galvo.hpp"
#include "core/modes/planar.hpp"

namespace calbox::sim {

RouterVerdict TwinKind::judge_fresh_job(const Scenario& s, const jobs::Correction*) const {
    throw ScenarioError(s.path + ": a " + s.machine.kind + " is not judged as a planar machine");
}

namespace {

using models::TomlReader;
using nlohmann::json;

std::string printed(const char* format, auto... values) {
    char line[256];
    std::snprintf(line, sizeof line, format, values...);
    return line;
}

json figures(double mean_mm, double rms_mm, double max_mm) {
    return {{"mean_mm", mean_mm}, {"rms_mm", rms_mm}, {"max_mm", max_mm}};
}

// A delta printer as its firmware is set now, over the printable area: the box corrected the
// printer itself.
class DeltaJudge final : public TwinJudge {
  public:
    explicit DeltaJudge(const TwinBench& bench) : bench_(bench) {}
    TwinVerdict before() const override {
        const auto j = bench_.judge_delta_printer();
        return {{std::nullopt, j.xy_rms, j.xy_max},
                printed("XY rms %.4f mm, max %.4f mm (the twin's truth, over the printable area)",
                        j.xy_rms, j.xy_max)};
    }
    TwinVerdict after(const std::optional<jobs::KeptCorrection>&) const override {
        const auto j = bench_.judge_delta_printer();
        return {{std::nullopt, j.xy_rms, j.xy_max},
                printed("XY rms %.4f mm, max %.4f mm", j.xy_rms, j.xy_max)};
    }

  private:
    const TwinBench& bench_;
};

// A galvo scanner: a fresh 30 x 30 grid of marks over the field less a pitch, then over the
// table's area through the table.
class GalvoJudge final : public TwinJudge {
  public:
    explicit GalvoJudge(const TwinBench& bench) : bench_(bench) {}
    TwinVerdict before() const override {
        const auto j = bench_.judge_galvo_scanner(
            [](Vec2 p) { return p; }, field_less_a_pitch(bench_.scenario().galvo_truth));
        return {{j.mean_mm, j.rms_mm, j.max_mm},
                printed("marks %.4f mm mean, %.4f mm worst (the twin's truth, a fresh 30 x 30 "
                        "grid over the field less a pitch)",
                        j.mean_mm, j.max_mm)};
    }
    TwinVerdict after(const std::optional<jobs::KeptCorrection>& kept) const override {
        if (!kept) throw std::runtime_error("the cycle completed but the box keeps no table");
        const auto j = bench_.judge_galvo_scanner(
            [&kept](Vec2 p) {
                const auto c = kept->correct({p.x, p.y});
                return Vec2{c.x, c.y};
            },
            {kept->min_x_mm, kept->min_y_mm, kept->max_x_mm, kept->max_y_mm});
        return {
            {j.mean_mm, j.rms_mm, j.max_mm},
            printed("marks through the table %.5f mm mean, %.5f mm worst", j.mean_mm, j.max_mm)};
    }

  private:
    const TwinBench& bench_;
};

// A planar machine's verdict on a fresh job half a pitch off the target's, as the before and
// after lines say it.
TwinVerdict fresh_job_before(const RouterVerdict& v) {
    return {{v.before.mean_mm, v.before.rms_mm, v.before.max_mm},
            printed("%.4f mm mean, %.4f mm worst (the twin's truth, a fresh job of %zu points "
                    "half a pitch off the target's)",
                    v.before.mean_mm, v.before.max_mm, v.holes)};
}
TwinVerdict fresh_job_through_model(const RouterVerdict& v) {
    const auto& a = *v.after;
    return {{a.mean_mm, a.rms_mm, a.max_mm},
            printed("through the error model %.5f mm mean, %.5f mm worst (%.1f %% less)", a.mean_mm,
                    a.max_mm, 100 * (1 - a.mean_mm / v.before.mean_mm))};
}

// A router, cartesian printer or gantry laser: a fresh job of holes half a pitch off the
// target's, drilled as commanded, then through the model the box keeps.
class PlanarJudge final : public TwinJudge {
  public:
    explicit PlanarJudge(const TwinBench& bench) : bench_(bench) {}
    TwinVerdict before() const override {
        return fresh_job_before(judge_planar_machine(bench_.scenario(), nullptr));
    }
    TwinVerdict after(const std::optional<jobs::KeptCorrection>& kept) const override {
        if (!kept) throw std::runtime_error("the cycle completed but the box keeps no error model");
        return fresh_job_through_model(judge_planar_machine(bench_.scenario(), &kept->correct));
    }

  private:
    const TwinBench& bench_;
};

// A cartesian printer as its firmware is set now (Klipper's, behind its host, carries the
// correction itself): a fresh job half a pitch off the target's, as commanded and through the
// model the box keeps, if it keeps one.
class CartesianJudge final : public TwinJudge {
  public:
    explicit CartesianJudge(const TwinBench& bench) : bench_(bench) {}
    TwinVerdict before() const override {
        return fresh_job_before(bench_.judge_cartesian_printer(nullptr));
    }
    TwinVerdict after(const std::optional<jobs::KeptCorrection>& kept) const override {
        if (kept) return fresh_job_through_model(bench_.judge_cartesian_printer(&kept->correct));
        const auto v = bench_.judge_cartesian_printer(nullptr);
        return {{v.before.mean_mm, v.before.rms_mm, v.before.max_mm},
                printed("as its firmware is set now %.5f mm mean, %.5f mm worst", v.before.mean_mm,
                        v.before.max_mm)};
    }

  private:
    const TwinBench& bench_;
};

// A planar machine's `sim verify`: a fresh job of holes half a pitch off the target's made as
// commanded, and with a result through the compensated G-code.
SimVerification verify_planar(const TwinKind& kind, const Scenario& s,
                              const std::optional<ResultFile>& result) {
    std::optional<modes::PlanarSolution> solution;
    if (result) solution = modes::planar_result_from_json(result->text, result->path);
    const jobs::Correction correct = [&solution](geometry::Point2 p) {
        return modes::planar_command_for(*solution, p);
    };
    const auto verdict = kind.judge_fresh_job(s, solution ? &correct : nullptr);
    const auto as_json = [](const RouterJudgement& r) {
        return figures(r.mean_mm, r.rms_mm, r.max_mm);
    };
    SimVerification v;
    v.lines.push_back(printed("before: %zu holes %.4f mm mean, %.4f RMS, %.4f worst", verdict.holes,
                              verdict.before.mean_mm, verdict.before.rms_mm,
                              verdict.before.max_mm));
    json j{{"schema", "calbox.sim-verify-router/1"},
           {"holes", verdict.holes},
           {"before", as_json(verdict.before)}};
    if (verdict.after) {
        v.lines.push_back(
            printed("through the compensated G-code: %.5f mm mean, %.5f RMS, %.5f worst",
                    verdict.after->mean_mm, verdict.after->rms_mm, verdict.after->max_mm));
        j["after"] = as_json(*verdict.after);
    }
    v.json = j.dump(1) + "\n";
    return v;
}

class DeltaKind final : public TwinKind {
  public:
    const char* truth_table() const override { return "delta"; }
    void read_truth(const std::string& path, const TruthTable* t, Scenario& s) const override {
        if (t == nullptr) return;
        models::DeltaSettings truth_delta = *s.machine.delta;
        models::read_delta_settings(path, t->table, "truth.delta", truth_delta);
        s.delta_truth = twin_params(truth_delta);
    }
    std::unique_ptr<MachineTwin> make_machine(const Scenario& s) const override {
        auto twin =
            std::make_unique<DeltaTwin>(s.delta_truth, s.delta_firmware,
                                        s.machine.firmware == "rrf"       ? DeltaDialect::rrf
                                        : s.machine.firmware == "klipper" ? DeltaDialect::klipper
                                                                          : DeltaDialect::marlin);
        if (s.zero_height_at_centre || s.levelled_by != "centre") twin->zero_height_at_centre();
        const double bed_radius_mm = s.machine.bed_radius_mm;
        if (s.levelled_by == "paper") twin->level_by_paper(0.8 * bed_radius_mm);
        if (s.levelled_by == "probe")
            twin->level_by_probe(0.9 * bed_radius_mm, 0.45 * bed_radius_mm);
        return twin;
    }
    std::unique_ptr<TwinJudge> make_judge(const TwinBench& bench) const override {
        return std::make_unique<DeltaJudge>(bench);
    }
    ToolKind tool() const override { return ToolKind::extruder; }
    // The firmware lines of a solve result sent to the scenario's printer, then commanded against
    // actual positions over the printable area.
    SimVerification verify(const Scenario& s,
                           const std::optional<ResultFile>& result) const override {
        std::vector<std::string> commands;
        if (result) commands = modes::result_from_json(result->text, result->path).commands;
        auto machine = make_machine(s);
        auto& delta = dynamic_cast<DeltaTwin&>(*machine);
        const double printable = s.machine.bed_radius_mm;
        DeltaJudgement judged;
        try {
            judged = judge_delta(delta, commands, printable);
        } catch (const std::exception& e) {
            throw std::runtime_error(std::string("the twin refused the commands: ") + e.what());
        }
        SimVerification v;
        v.lines.push_back(printed("before: XY %.4f mm RMS, worst %.4f mm; height range %.4f mm",
                                  judged.xy_rms_before, judged.xy_max_before,
                                  judged.height_range_before));
        if (!commands.empty())
            v.lines.push_back(
                printed("after %zu command(s): XY %.4f mm RMS, worst %.4f mm; height range %.4f mm",
                        commands.size(), judged.xy_rms, judged.xy_max, judged.height_range_after));
        v.json = json{{"schema", "calbox.sim-verify/1"},
                      {"printable_radius_mm", printable},
                      {"before",
                       {{"xy_rms_mm", judged.xy_rms_before},
                        {"xy_max_mm", judged.xy_max_before},
                        {"height_range_mm", judged.height_range_before}}},
                      {"after",
                       {{"xy_rms_mm", judged.xy_rms},
                        {"xy_max_mm", judged.xy_max},
                        {"height_range_mm", judged.height_range_after}}},
                      {"commands", commands}}
                     .dump(1) +
                 "\n";
        return v;
    }
};

class GalvoKind final : public TwinKind {
  public:
    const char* truth_table() const override { return "galvo"; }
    void read_truth(const std::string& path, const TruthTable* table, Scenario& s) const override {
        auto& t = s.galvo_truth;
        if (table != nullptr) {
            TomlReader r(path, table->table, "truth.galvo");
            int seed = 0;
            r.integer("seed", seed, 0, 1000000);
            if (seed > 0)
                t = random_galvo_truth(static_cast<unsigned>(seed), s.machine.galvo->field_size_mm);
            r.number("gain_x", t.gain_x, -0.05, 0.05);
            r.number("gain_y", t.gain_y, -0.05, 0.05);
            r.number("offset_x_mm", t.offset_x_mm, -10, 10);
            r.number("offset_y_mm", t.offset_y_mm, -10, 10);
            r.number("skew_deg", t.skew_deg, -2, 2);
            r.number("rotation_deg", t.rotation_deg, -180, 180);
            r.number("mirror_bow_mm", t.mirror_bow_mm, -10, 10);
            r.number("lens_radial_mm", t.lens_radial_mm, -10, 10);
            r.number("ripple_mm", t.ripple_mm, 0, 1);
            r.number("ripple_period_mm", t.ripple_period_mm, 1, 1000);
            r.boolean("x_reversed", t.x_reversed);
            r.finish();
        }
        t.field_size_mm = s.machine.galvo->field_size_mm;
        t.substrate_height_mm = s.machine.galvo->substrate_height_mm;
    }
    std::unique_ptr<MachineTwin> make_machine(const Scenario& s) const override {
        return std::make_unique<GalvoTwin>(s.galvo_truth);
    }
    std::unique_ptr<TwinJudge> make_judge(const TwinBench& bench) const override {
        return std::make_unique<GalvoJudge>(bench);
    }
    ToolKind tool() const override { return ToolKind::laser; }
    // A fresh 30 x 30 grid of marks over the table's area (or the field less a pitch) burned as
    // commanded, then through the result's table.
    SimVerification verify(const Scenario& s,
                           const std::optional<ResultFile>& result) const override {
        std::optional<modes::GalvoSolution> solution;
        if (result) solution = modes::galvo_result_from_json(result->text, result->path);
        const auto& t = solution ? &solution->fit.table : nullptr;
        const std::array<double, 4> area =
            t ? std::array<double, 4>{t->min_x_mm, t->min_y_mm, t->max_x_mm, t->max_y_mm}
              : field_less_a_pitch(s.galvo_truth);
        const auto fresh = fresh_grid(area, 30);
        const auto before = judge_galvo(s.galvo_truth, fresh, [](Vec2 p) { return p; });
        SimVerification v;
        v.lines.push_back(printed("before: %zu marks %.4f mm mean, %.4f RMS, %.4f worst",
                                  before.points, before.mean_mm, before.rms_mm, before.max_mm));
        json j{{"schema", "calbox.sim-verify-galvo/1"},
               {"area_mm", area},
               {"before", figures(before.mean_mm, before.rms_mm, before.max_mm)}};
        if (t) {
            const auto after = judge_galvo(s.galvo_truth, fresh, [t](Vec2 p) {
                const auto c = t->command_for({p.x, p.y});
                return Vec2{c.x, c.y};
            });
            v.lines.push_back(printed("after the table: %.5f mm mean, %.5f RMS, %.5f worst",
                                      after.mean_mm, after.rms_mm, after.max_mm));
            j["after"] = figures(after.mean_mm, after.rms_mm, after.max_mm);
        }
        v.json = j.dump(1) + "\n";
        return v;
    }
};

class RouterKind final : public TwinKind {
  public:
    const char* truth_table() const override { return "router"; }
    void read_truth(const std::string& path, const TruthTable* table, Scenario& s) const override {
        auto& t = s.router_truth;
        t.travel_x_mm = s.machine.bed_size_x_mm;
        t.travel_y_mm = s.machine.bed_size_y_mm;
        if (table == nullptr) return;
        TomlReader reader(path, table->table, "truth.router");
        int seed = 0;
        reader.integer("seed", seed, 0, 1000000);
        if (seed > 0)
            t = random_router_truth(static_cast<unsigned>(seed), t.travel_x_mm, t.travel_y_mm);
        reader.number("scale_x", t.scale_x, -0.05, 0.05);
        reader.number("scale_y", t.scale_y, -0.05, 0.05);
        reader.number("squareness_rad", t.squareness_rad, -0.05, 0.05);
        reader.number("bow_x_mm", t.bow_x_mm, -10, 10);
        reader.number("bow_y_mm", t.bow_y_mm, -10, 10);
        reader.number("gantry_yaw_rad_per_mm", t.gantry_yaw_rad_per_mm, -1e-3, 1e-3);
        reader.number("tool_length_mm", t.tool_length_mm, 0, 500);
        reader.number("screw_error_mm", t.screw_error_mm, 0, 1);
        reader.number("backlash_x_mm", t.backlash_x_mm, 0, 2);
        reader.number("backlash_y_mm", t.backlash_y_mm, 0, 2);
        reader.number("g54_x_mm", t.g54_x_mm, -10000, 10000);
        reader.number("g54_y_mm", t.g54_y_mm, -10000, 10000);
        reader.number("g54_z_mm", t.g54_z_mm, -10000, 10000);
        reader.finish();
    }
    std::unique_ptr<MachineTwin> make_machine(const Scenario& s) const override {
        auto router = std::make_unique<RouterTwin>(s.router_truth);
        // A sheet the box finds on the bed at start is there for the probe to touch too.
        if (const auto& p = s.placement; p && p->on_bed_at_start && !p->card)
            router->lay_sheet(p->sheet, p->thickness_mm);
        return router;
    }
    std::unique_ptr<TwinJudge> make_judge(const TwinBench& bench) const override {
        return std::make_unique<PlanarJudge>(bench);
    }
    ToolKind tool() const override { return ToolKind::spindle; }
    SimVerification verify(const Scenario& s,
                           const std::optional<ResultFile>& result) const override {
        return verify_planar(*this, s, result);
    }
    RouterVerdict judge_fresh_job(const Scenario& s,
                                  const jobs::Correction* correct) const override {
        return judge_router_fresh_holes(s.router_truth, s.machine, correct);
    }
    // A router cuts holes: the camera sees the sheet's top with the holes in it.
    std::vector<StrokeSegment> on_the_bed(const Scenario& s,
                                          std::vector<StrokeSegment> strokes) const override {
        std::vector<Stroke> cuts;
        cuts.reserve(strokes.size());
        for (const auto& c : strokes)
            cuts.push_back({c.a_mm, c.b_mm, c.a_mm, c.b_mm, c.width_mm, 0});
        return holes_on_the_sheet(cuts, s.machine.planar->surface_height_mm);
    }
};

// A cartesian printer, or a gantry laser: the same gantry's errors, its marks laid by an extruder
// or burned by the laser's spot.
class CartesianKind final : public TwinKind {
  public:
    explicit CartesianKind(ToolKind tool) : tool_(tool) {}
    const char* truth_table() const override { return "cartesian"; }
    void read_truth(const std::string& path, const TruthTable* table, Scenario& s) const override {
        if (table == nullptr) return;
        TomlReader r(path, table->table, "truth.cartesian");
        r.number("scale_error_x", s.cartesian_truth.scale_error_x, -0.05, 0.05);
        r.number("scale_error_y", s.cartesian_truth.scale_error_y, -0.05, 0.05);
        r.number("squareness_error_deg", s.cartesian_truth.squareness_error_deg, -5, 5);
        r.finish();
    }
    std::unique_ptr<MachineTwin> make_machine(const Scenario& s) const override {
        return std::make_unique<CartesianTwin>(s.cartesian_truth, CartesianFirmware{},
                                               s.machine.firmware == "grbl");
    }
    std::unique_ptr<TwinJudge> make_judge(const TwinBench& bench) const override {
        return std::make_unique<CartesianJudge>(bench);
    }
    ToolKind tool() const override { return tool_; }
    RouterVerdict judge_fresh_job(const Scenario& s,
                                  const jobs::Correction* correct) const override {
        return judge_cartesian_fresh_points(s.cartesian_truth, s.machine, correct);
    }
    SimVerification verify(const Scenario& s,
                           const std::optional<ResultFile>& result) const override {
        return verify_planar(*this, s, result);
    }

  private:
    ToolKind tool_;
};

template <class Kind>
const TwinKind& twin_of() {
    static const Kind kind;
    return kind;
}
const TwinKind& cartesian_printer_twin() {
    static const CartesianKind kind(ToolKind::extruder);
    return kind;
}
const TwinKind& gantry_laser_twin() {
    static const CartesianKind kind(ToolKind::laser);
    return kind;
}

// Each machine kind's twin, checked at compile time against core/models/machine_kinds.hpp.
struct TwinRow {
    std::string_view kind;
    const TwinKind& (*twin)();
};
constexpr std::array<TwinRow, 5> kTwins{{
    {"delta", twin_of<DeltaKind>},
    {"cartesian", cartesian_printer_twin},
    {"router", twin_of<RouterKind>},
    {"laser", gantry_laser_twin},
    {"galvo", twin_of<GalvoKind>},
}};
static_assert(models::names_every_machine_kind(kTwins),
              "every machine kind of core/models/machine_kinds.hpp has one twin here");

}  // namespace

const TwinKind& twin_kind_of(const models::MachineFile& machine) {
    for (const auto& row : kTwins)
        if (row.kind == machine.kind) return row.twin();
    throw ScenarioError("the twin has no " + machine.kind + " machine");
}

std::set<std::string> truth_table_names() {
    std::set<std::string> names;
    for (const auto& row : kTwins) names.emplace(row.twin().truth_table());
    return names;
}

std::unique_ptr<TwinJudge> make_twin_judge(const TwinBench& bench) {
    return twin_kind_of(bench.scenario().machine).make_judge(bench);
}

}  // namespace calbox::sim
