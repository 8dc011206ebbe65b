#include "board/sim/router_twin.hpp"

#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>

#include "board/sim/delta_judge.hpp"
#include "core/targets/planar_target.hpp"

namespace calbox::sim {
namespace {

struct Matrix3 {
    double m[3][3];
    Vec3 operator*(const Vec3& v) const {
        return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
    }
    Matrix3 operator*(const Matrix3& o) const {
        Matrix3 r{};
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k) r.m[i][j] += m[i][k] * o.m[k][j];
        return r;
    }
};

Matrix3 about_x(double a) {
    return {{{1, 0, 0}, {0, std::cos(a), -std::sin(a)}, {0, std::sin(a), std::cos(a)}}};
}
Matrix3 about_y(double a) {
    return {{{std::cos(a), 0, std::sin(a)}, {0, 1, 0}, {-std::sin(a), 0, std::cos(a)}}};
}
Matrix3 about_z(double a) {
    return {{{std::cos(a), -std::sin(a), 0}, {std::sin(a), std::cos(a), 0}, {0, 0, 1}}};
}

// A parabola through an axis's ends, `bow` at mid-travel.
double bow_at(double bow, double s, double travel) {
    const double u = s / travel;
    return 4 * bow * u * (1 - u);
}

}  // namespace

RouterTruth random_router_truth(unsigned seed, double travel_x_mm, double travel_y_mm) {
    std::mt19937 rng(seed * 104729u + 31u);
    std::uniform_real_distribution<double> u(-1, 1);
    const auto sign = [&] { return u(rng) < 0 ? -1.0 : 1.0; };
    RouterTruth t;
    t.travel_x_mm = travel_x_mm;
    t.travel_y_mm = travel_y_mm;
    // Belt or screw pitch most of a percent off, a gantry several milliradians out of square,
    // guides bowed by one or two millimetres, the gantry yawing as much again over its travel
    // (the seed's router (scales of -0.64 % and 0.56 %,
    // 6 mrad out of square, its x axis bowed 1.4 mm over 250 mm, 2.3e-5 rad/mm of yaw) showed
    // 1.54 mm of mean error norm in its own frame.
    t.scale_x = sign() * (0.008 + 0.004 * std::abs(u(rng)));
    t.scale_y = sign() * (0.008 + 0.004 * std::abs(u(rng)));
    t.squareness_rad = sign() * (0.008 + 0.004 * std::abs(u(rng)));
    t.bow_x_mm = sign() * (1.5 + 0.7 * std::abs(u(rng)));
    t.bow_y_mm = sign() * (1.5 + 0.7 * std::abs(u(rng)));
    t.gantry_yaw_rad_per_mm = sign() * (2e-5 + 1e-5 * std::abs(u(rng)));
    t.gantry_pitch_rad_per_mm = 4e-6 * u(rng);
    t.gantry_roll_rad_per_mm = 4e-6 * u(rng);
    t.carriage_pitch_rad_per_mm = 4e-6 * u(rng);
    t.carriage_roll_rad_per_mm = 4e-6 * u(rng);
    t.tool_length_mm = 80 + 20 * u(rng);
    t.screw_error_mm = 0.004 + 0.002 * u(rng);
    t.screw_lead_mm = 5;
    t.backlash_x_mm = 0.05 + 0.03 * u(rng);
    t.backlash_y_mm = 0.05 + 0.03 * u(rng);
    return t;
}

Vec3 router_tool_position_mm(const RouterTruth& t, const Vec3& c,
                             std::array<bool, 2> moving_positive) {
    // Each drive: scale, the screw's cyclic error, and backlash (the carriage lags half the slack
    // behind the way it last moved).
    const double k = 2 * kPi / t.screw_lead_mm;
    const double x = c.x * (1 + t.scale_x) + t.screw_error_mm * std::sin(k * c.x) +
                     (moving_positive[0] ? -0.5 : 0.5) * t.backlash_x_mm;
    const double y = c.y * (1 + t.scale_y) + t.screw_error_mm * std::sin(k * c.y + 1.0) +
                     (moving_positive[1] ? -0.5 : 0.5) * t.backlash_y_mm;
    // The gantry's origin (its x = 0 end) runs along a leaning, bowed path; the gantry turns as
    // it goes (yaw about z, pitch about x, roll about y).
    const Vec3 gantry_origin{
        y * std::sin(t.squareness_rad) + bow_at(t.bow_y_mm, c.y, t.travel_y_mm),
        y * std::cos(t.squareness_rad), 0};
    const Matrix3 gantry = about_z(t.gantry_yaw_rad_per_mm * c.y) *
                           about_x(t.gantry_pitch_rad_per_mm * c.y) *
                           about_y(t.gantry_roll_rad_per_mm * c.y);
    // The carriage runs along the gantry on a bowed path and pitches (about y) and rolls (about
    // x) as it goes; the tool point hangs below it.
    const Vec3 carriage_on_gantry{x, bow_at(t.bow_x_mm, c.x, t.travel_x_mm), 0};
    const Matrix3 carriage =
        about_y(t.carriage_pitch_rad_per_mm * c.x) * about_x(t.carriage_roll_rad_per_mm * c.x);
    const Vec3 tool{0, 0, -(t.tool_length_mm - c.z)};
    const Vec3 p = gantry_origin + gantry * (carriage_on_gantry + carriage * tool);
    return {p.x, p.y, p.z + t.tool_length_mm};
}

void RouterTwin::home() {
    homed_ = true;
    last_commanded_ = {0, 0, 0};
    moving_positive_ = {true, true};
}

Vec3 RouterTwin::actual_position_mm(const Vec3& commanded_in_g54) const {
    // A point in G54 as it is now, in the work frame of the truth's touch-off.
    const Vec3 commanded{commanded_in_g54.x + g54_x_mm_ - truth_.g54_x_mm,
                         commanded_in_g54.y + g54_y_mm_ - truth_.g54_y_mm, commanded_in_g54.z};
    if (commanded.x < -1 || commanded.y < -1 || commanded.x > truth_.travel_x_mm + 1 ||
        commanded.y > truth_.travel_y_mm + 1)
        throw OutOfReach("the router cannot reach X" + std::to_string(commanded.x) + " Y" +
                         std::to_string(commanded.y));
    if (commanded.x != last_commanded_.x) moving_positive_[0] = commanded.x > last_commanded_.x;
    if (commanded.y != last_commanded_.y) moving_positive_[1] = commanded.y > last_commanded_.y;
    last_commanded_ = commanded;
    return router_tool_position_mm(truth_, commanded, moving_positive_);
}

void RouterTwin::lay_sheet(const StockSheet& sheet, double thickness_mm) {
    sheet_corners_ = SheetScene(sheet, 1).corners();
    sheet_thickness_mm_ = thickness_mm;
}

Vec3 RouterTwin::probe_down(const Vec3& from, double to_z) {
    const Vec3 in_truth{from.x + g54_x_mm_ - truth_.g54_x_mm, from.y + g54_y_mm_ - truth_.g54_y_mm,
                        from.z};
    // The tool's real height over what lies under it, for the tool commanded to Z `z`.
    const auto clearance = [&](double z) {
        const Vec3 tool =
            router_tool_position_mm(truth_, {in_truth.x, in_truth.y, z}, moving_positive_);
        bool on_sheet = sheet_corners_.has_value();
        for (std::size_t i = 0; on_sheet && i < 4; ++i) {
            const Vec2 a = (*sheet_corners_)[i], b = (*sheet_corners_)[(i + 1) % 4];
            on_sheet = (b.x - a.x) * (tool.y - a.y) - (b.y - a.y) * (tool.x - a.x) > 0;
        }
        return tool.z - (on_sheet ? sheet_thickness_mm_ : 0.0);
    };
    if (clearance(from.z) <= 0)
        throw ProbeAlarm(4, "the probe touches before G38.2 moves (the tool at Z" +
                                std::to_string(from.z) + ")");
    if (clearance(to_z) > 0)
        throw ProbeAlarm(5, "the probe touched nothing down to Z" + std::to_string(to_z));
    // The height changes with Z by one to within the tilts' cosines: halving to far below a
    // probe's repeatability.
    double above = from.z, below = to_z;
    while (above - below > 1e-7) {
        const double mid = (above + below) / 2;
        (clearance(mid) > 0 ? above : below) = mid;
    }
    const double touched = below + std::normal_distribution<double>(0, 0.002)(probe_noise_);
    return {from.x, from.y, touched};
}

std::optional<std::vector<std::string>> RouterTwin::settings_command(const gcode::Line& line) {
    if (line.is('G', 17) || line.is('M', 2) || line.is('M', 30)) return std::vector<std::string>{};
    // grbl's G10 L2 P1: G54's zero set to the machine coordinates given (the axes given).
    if (line.is('G', 10) && line.value('L') == 2.0 && line.value('P') == 1.0) {
        if (const auto x = line.value('X')) g54_x_mm_ = *x;
        if (const auto y = line.value('Y')) g54_y_mm_ = *y;
        return std::vector<std::string>{};
    }
    return std::nullopt;
}

std::optional<std::vector<std::string>> RouterTwin::system_command(std::string_view text) {
    if (text != "$#") return std::nullopt;
    return grbl_offsets_report(g54_x_mm_, g54_y_mm_, truth_.g54_z_mm);
}

std::vector<Vec2> drilled_hole_centres_mm(RouterTwin& twin, const std::string& job) {
    ToolSettings tool;
    tool.kind = ToolKind::spindle;
    tool.tool_width_mm = 1;
    GcodeRunner runner(twin, tool);
    std::istringstream in(job);
    runner.run(in);
    // A hole is where a run of cuts starts: the bottom of its plunge (the first cut is the
    // plunge's last piece below the surface, the tool at the hole's axis).
    std::vector<Vec2> holes;
    int previous_line = -10;
    for (const auto& s : runner.result().strokes) {
        const bool plunge = s.commanded_a_mm.x == s.commanded_b_mm.x &&
                            s.commanded_a_mm.y == s.commanded_b_mm.y &&
                            s.commanded_b_mm.z < s.commanded_a_mm.z;
        if (plunge && s.line != previous_line) holes.push_back({s.b_mm.x, s.b_mm.y});
        if (plunge) holes.back() = {s.b_mm.x, s.b_mm.y};
        previous_line = s.line;
    }
    return holes;
}

std::vector<StrokeSegment> holes_on_the_sheet(const std::vector<Stroke>& cuts,
                                              double surface_height_mm) {
    std::vector<StrokeSegment> out;
    out.reserve(cuts.size());
    for (const auto& s : cuts)
        out.push_back({{s.a_mm.x, s.a_mm.y, surface_height_mm},
                       {s.b_mm.x, s.b_mm.y, surface_height_mm},
                       s.width_mm});
    return out;
}

namespace {

// Points half a pitch off the machine's target grid, over the same area: none of them a hole or
// dot the calibration saw.
std::vector<targets::PlanarHole> fresh_points(const targets::PlanarTarget& target) {
    std::vector<targets::PlanarHole> holes;
    for (int r = 0; r + 1 < target.rows; ++r)
        for (int c = 0; c + 1 < target.columns; ++c)
            holes.push_back({{c, r},
                             {target.first_mm.x + (c + 0.5) * target.pitch_mm,
                              target.first_mm.y + (r + 0.5) * target.pitch_mm},
                             false});
    return holes;
}

}  // namespace

RouterJudgement judge_router(const RouterTruth& truth, const std::vector<Vec2>& intended_mm,
                             const std::string& job) {
    RouterTwin twin(truth);
    const auto holes = drilled_hole_centres_mm(twin, job);
    if (holes.size() != intended_mm.size())
        throw MachineError("judge: the job drilled " + std::to_string(holes.size()) +
                           " holes for " + std::to_string(intended_mm.size()) + " points");
    std::vector<Vec3> drilled, intended;
    for (std::size_t i = 0; i < holes.size(); ++i) {
        drilled.push_back({holes[i].x, holes[i].y, 0});
        intended.push_back({intended_mm[i].x, intended_mm[i].y, 0});
    }
    return judge_placed(drilled, intended);
}

RouterVerdict judge_router_fresh_holes(const RouterTruth& truth, const models::MachineFile& machine,
                                       const jobs::Correction* correct) {
    const auto target = targets::make_planar_target(machine);
    const auto holes = fresh_points(target);
    std::vector<Vec2> intended;
    intended.reserve(holes.size());
    for (const auto& h : holes) intended.push_back({h.centre_mm.x, h.centre_mm.y});
    const std::string job = targets::write_drilling_job(machine, holes, target.hole_diameter_mm,
                                                        target.large_diameter_mm, "fresh holes");
    RouterVerdict v;
    v.holes = holes.size();
    v.before = judge_router(truth, intended, job);
    if (correct != nullptr) {
        jobs::CompensateReport report;
        // The fresh holes lie inside the measured area: the correction is the model's there.
        const jobs::JobFrame frame{
            jobs::flavour_of_firmware(machine.firmware), {geometry::Point2{}}, {}, {}};
        const std::string compensated =
            jobs::compensate_gcode(job, {*correct, {}}, frame, {}, report);
        v.after = judge_router(truth, intended, compensated);
    }
    return v;
}

RouterVerdict judge_cartesian_fresh_points(const CartesianErrors& truth,
                                           const models::MachineFile& machine,
                                           const jobs::Correction* correct) {
    return judge_cartesian_fresh_points(CartesianTwin(truth), machine, correct);
}

RouterVerdict judge_cartesian_fresh_points(CartesianTwin twin, const models::MachineFile& machine,
                                           const jobs::Correction* correct) {
    twin.home();
    const auto points = fresh_points(targets::make_planar_target(machine));
    std::vector<Vec3> intended, before, after;
    for (const auto& p : points) {
        intended.push_back({p.centre_mm.x, p.centre_mm.y, 0});
        before.push_back(twin.actual_position_mm({p.centre_mm.x, p.centre_mm.y, 0}));
        if (correct != nullptr) {
            const auto c = (*correct)(p.centre_mm);
            after.push_back(twin.actual_position_mm({c.x, c.y, 0}));
        }
    }
    RouterVerdict v;
    v.holes = points.size();
    v.before = judge_placed(before, intended);
    if (correct != nullptr) v.after = judge_placed(after, intended);
    return v;
}

}  // namespace calbox::sim
