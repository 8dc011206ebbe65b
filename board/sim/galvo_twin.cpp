#include "board/sim/galvo_twin.hpp"

#include <cmath>
#include <random>

#include "board/sim/delta_judge.hpp"

namespace calbox::sim {

GalvoTruth random_galvo_truth(unsigned seed, double field_size_mm) {
    std::mt19937 rng(seed * 7919u + 17u);
    std::uniform_real_distribution<double> u(-1, 1);
    GalvoTruth t;
    t.field_size_mm = field_size_mm;
    const double scale = field_size_mm / 110;
    t.gain_x = 0.004 * u(rng);
    t.gain_y = 0.004 * u(rng);
    t.offset_x_mm = 0.3 * scale * u(rng);
    t.offset_y_mm = 0.3 * scale * u(rng);
    t.skew_deg = 0.08 * u(rng);
    t.rotation_deg = 0.5 * u(rng);
    t.mirror_bow_mm = (0.45 + 0.15 * u(rng)) * scale;
    t.lens_radial_mm = 0.3 * scale * u(rng);
    t.ripple_mm = (0.01 + 0.005 * u(rng)) * scale;
    t.ripple_period_mm = (60 + 20 * u(rng)) * scale;
    t.ripple_phase_rad = 3.14159265358979 * u(rng);
    return t;
}

Vec2 galvo_mark_position_mm(const GalvoTruth& t, Vec2 c) {
    const double half = t.field_size_mm / 2;
    double x = c.x * (1 + t.gain_x) + t.offset_x_mm;
    double y = c.y * (1 + t.gain_y) + t.offset_y_mm;
    x += std::tan(radians(t.skew_deg)) * y;
    // The first mirror's beam travels further to the field the more the second one turns it.
    x += t.mirror_bow_mm * (x / half) * (y / half) * (y / half);
    // The lens: radial, zero on the axis, `lens_radial_mm` at the corners.
    const double corner = half * std::sqrt(2.0);
    const double r2 = (x * x + y * y) / (corner * corner);
    const double radial = t.lens_radial_mm / corner * r2;
    x += x * radial;
    y += y * radial;
    const double k = 2 * 3.14159265358979323846 / t.ripple_period_mm;
    const double rx = t.ripple_mm * std::sin(k * y + t.ripple_phase_rad);
    const double ry = t.ripple_mm * std::sin(k * x + 0.5 * t.ripple_phase_rad);
    x += rx;
    y += ry;
    if (t.x_reversed) x = -x;
    const double a = radians(t.rotation_deg), ca = std::cos(a), sa = std::sin(a);
    return {ca * x - sa * y, sa * x + ca * y};
}

Vec3 GalvoTwin::actual_position_mm(const Vec3& commanded) const {
    const double half = truth_.field_size_mm / 2;
    if (std::abs(commanded.x) > half + 1e-9 || std::abs(commanded.y) > half + 1e-9) {
        throw MachineError("the scanner cannot reach X" + std::to_string(commanded.x) + " Y" +
                           std::to_string(commanded.y) + " (field +-" + std::to_string(half) +
                           " mm)");
    }
    const Vec2 p = galvo_mark_position_mm(truth_, {commanded.x, commanded.y});
    return {p.x, p.y, truth_.substrate_height_mm};
}

std::optional<std::vector<std::string>> GalvoTwin::settings_command(const gcode::Line& line) {
    if (line.is('M', 500)) return std::vector<std::string>{"echo:Settings Stored", "ok"};
    if (line.is('M', 503)) return std::vector<std::string>{"echo:; (no geometry settings)", "ok"};
    return std::nullopt;
}

GalvoJudgement judge_galvo(const GalvoTruth& truth, const std::vector<Vec2>& intended_mm,
                           const std::function<Vec2(Vec2)>& command_for) {
    std::vector<Vec3> marked, intended;
    marked.reserve(intended_mm.size());
    for (const auto& p : intended_mm) {
        const Vec2 m = galvo_mark_position_mm(truth, command_for(p));
        marked.push_back({m.x, m.y, 0});
        intended.push_back({p.x, p.y, 0});
    }
    return judge_placed(marked, intended);
}

std::vector<Vec2> fresh_grid(const std::array<double, 4>& area_mm, int count) {
    std::vector<Vec2> out;
    for (int r = 0; r < count; ++r)
        for (int c = 0; c < count; ++c)
            out.push_back({area_mm[0] + (area_mm[2] - area_mm[0]) * (c + 0.5) / count,
                           area_mm[1] + (area_mm[3] - area_mm[1]) * (r + 0.5) / count});
    return out;
}

std::array<double, 4> field_less_a_pitch(const GalvoTruth& truth) {
    const double half = truth.field_size_mm / 2 - truth.field_size_mm / 31;
    return {-half, -half, half, half};
}

std::vector<StrokeSegment> with_burn_faults(const std::vector<Stroke>& burned,
                                            const BurnFaults& faults) {
    std::vector<StrokeSegment> out;
    out.reserve(burned.size() + faults.spatter_at_mm.size());
    for (const auto& s : burned) {
        bool misfired = false;
        for (const auto& m : faults.misfires_at_mm)
            misfired = misfired || std::hypot(s.commanded_a_mm.x - m.x, s.commanded_a_mm.y - m.y) <
                                       faults.misfire_radius_mm;
        if (!misfired) out.push_back({s.a_mm, s.b_mm, s.width_mm});
    }
    // A blob: a stroke of no length is a round spot of its width, on the marked surface.
    const double z = burned.empty() ? 0.0 : burned.front().a_mm.z;
    for (const auto& p : faults.spatter_at_mm)
        out.push_back({{p.x, p.y, z}, {p.x, p.y, z}, 2 * faults.spatter_radius_mm});
    return out;
}

}  // namespace calbox::sim
