#include "board/sim/twin_judge.hpp"

#include <cstdio>
#include <stdexcept>

#include "board/sim/scenario.hpp"
#include "board/sim/twin_kind.hpp"

namespace calbox::sim {
namespace {

std::string printed(const char* format, double a, double b) {
    char line[192];
    std::snprintf(line, sizeof line, format, a, b);
    return line;
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
    TwinVerdict after(const std::optional<targets::KeptCorrection>&) const override {
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
    TwinVerdict after(const std::optional<targets::KeptCorrection>& kept) const override {
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

// A router, cartesian printer or gantry laser: a fresh job of holes half a pitch off the
// target's, drilled as commanded, then through the model the box keeps.
class PlanarJudge final : public TwinJudge {
  public:
    explicit PlanarJudge(const TwinBench& bench) : bench_(bench) {}
    TwinVerdict before() const override {
        const auto v = judge_planar_machine(bench_.scenario(), nullptr);
        char line[192];
        std::snprintf(line, sizeof line,
                      "%.4f mm mean, %.4f mm worst (the twin's truth, a fresh job of %zu points "
                      "half a pitch off the target's)",
                      v.before.mean_mm, v.before.max_mm, v.holes);
        return {{v.before.mean_mm, v.before.rms_mm, v.before.max_mm}, line};
    }
    TwinVerdict after(const std::optional<targets::KeptCorrection>& kept) const override {
        if (!kept) throw std::runtime_error("the cycle completed but the box keeps no error model");
        const auto v = judge_planar_machine(bench_.scenario(), &kept->correct);
        const auto& a = *v.after;
        char line[192];
        std::snprintf(line, sizeof line,
                      "through the error model %.5f mm mean, %.5f mm worst (%.1f %% less)",
                      a.mean_mm, a.max_mm, 100 * (1 - a.mean_mm / v.before.mean_mm));
        return {{a.mean_mm, a.rms_mm, a.max_mm}, line};
    }

  private:
    const TwinBench& bench_;
};

}  // namespace

std::unique_ptr<TwinJudge> delta_judge(const TwinBench& bench) {
    return std::make_unique<DeltaJudge>(bench);
}
std::unique_ptr<TwinJudge> galvo_judge(const TwinBench& bench) {
    return std::make_unique<GalvoJudge>(bench);
}
std::unique_ptr<TwinJudge> planar_judge(const TwinBench& bench) {
    return std::make_unique<PlanarJudge>(bench);
}

std::unique_ptr<TwinJudge> make_twin_judge(const TwinBench& bench) {
    return twin_kind_of(bench.scenario().machine).make_judge(bench);
}

}  // namespace calbox::sim
