#include "core/modes/registration.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>

#include "core/geometry/line_fit.hpp"
#include "core/geometry/placement.hpp"
#include "core/modes/bed_view.hpp"
#include "core/modes/json_file.hpp"
#include "core/number_text.hpp"
#include "core/vision/cross_mark.hpp"
#include "core/vision/markers.hpp"
#include "core/vision/spots.hpp"

namespace calbox::modes {

using geometry::Point2;

namespace {

constexpr const char* kRegistrationSchema = "calbox.registration/1";

std::string drawing_text(Point2 p) {
    return "X" + number_text("%.2f", p.x) + " Y" + number_text("%.2f", p.y);
}

struct Candidate {
    Point2 machine_mm;
    double sigma_mm = 0;
};

// One way the drawing's marks fall on the candidates: which candidate each mark is, and the
// rigid placement that put them there.
struct MarkMatching {
    std::vector<std::size_t> candidate_of_mark;
    double rotation_rad = 0;
    double misfit_mm = 0;  // the sum of the marks' distances from their candidates
};

}  // namespace

namespace {

// The photo's marks of the printed size and shape, on the machine, enough for the drawing's.
std::vector<Candidate> mark_candidates(const geometry::CameraModel& camera,
                                       const geometry::BedPlane& plane,
                                       const vision::GrayView& photo, const BedToMachine& map,
                                       const RegistrationRequest& request, double px_per_mm) {
    const auto& marks = request.marks_drawing_mm;
    const double h = request.surface_height_mm;
    const bool crosses = request.kind == MarkKind::crosses;
    const std::string what = crosses ? "crosses" : "round marks";
    vision::SpotSettings spot_settings;
    spot_settings.polarity = vision::MarkPolarity::dark;
    spot_settings.mark_diameter_px = request.mark_diameter_mm * px_per_mm;
    if (crosses) {
        // The median filter that takes the specks keeps a bar only when it is narrower than it:
        // the largest odd size under the bar's width (an even one is no median's size: a bar
        // 3 to 6 px wide gave 2 or 4, and the photo was refused by the filter, not measured).
        const int bar_px = static_cast<int>(request.cross_line_mm * px_per_mm);
        spot_settings.median_kernel_px = std::clamp(bar_px - 1 - (bar_px % 2 != 0), 1, 5);
    }
    const auto found = vision::find_spots(photo, spot_settings);
    // Marks of the size printed, whole: a disc's area, or two crossed bars' (isotropic both).
    const double d = request.mark_diameter_mm, w = request.cross_line_mm;
    const double expected_area_px =
        (crosses ? 2 * d * w - w * w : std::numbers::pi * 0.25 * d * d) * px_per_mm * px_per_mm;
    std::vector<Candidate> candidates;
    std::vector<Point2> centres_px;
    std::vector<double> sigmas_px;
    for (const auto& s : found.spots) {
        if (s.touches_border || s.elongation > 1.25) continue;
        if (s.area_px < 0.6 * expected_area_px || s.area_px > 1.6 * expected_area_px) continue;
        if (crosses) {
            // The blob finds it; its bars' centre lines measure it.
            const auto cross =
                vision::measure_cross(photo, s.centre_px, d * px_per_mm, w * px_per_mm);
            if (!cross) continue;
            centres_px.push_back(cross->centre_px);
            sigmas_px.push_back(cross->sigma_px);
            continue;
        }
        centres_px.push_back(s.centre_px);
        sigmas_px.push_back(s.sigma_px);
    }
    if (!centres_px.empty()) {
        const auto on_bed = geometry::pixels_to_bed(camera, plane, centres_px, h);
        for (std::size_t k = 0; k < on_bed.size(); ++k)
            candidates.push_back(
                {map.machine_of({on_bed[k].x, on_bed[k].y}), sigmas_px[k] / px_per_mm});
    }
    if (candidates.size() < marks.size())
        throw RegistrationError("the photo shows " + std::to_string(candidates.size()) + " " +
                                what + " " + number_text("%.1f", request.mark_diameter_mm) +
                                " mm across, the drawing has " + std::to_string(marks.size()) +
                                ": are they printed dark, whole and in view?");

    return candidates;
}

// Each pair of candidates as far apart as the first two marks places the drawing one way
// (turned, shifted); the other marks must then each lie on a candidate within `reach_mm`.
struct NearestCandidate {
    std::size_t index;
    double distance_mm;
};
// The candidate nearest `at` within `reach_mm` (the first of equals), or nothing.
std::optional<NearestCandidate> nearest_candidate(const std::vector<Candidate>& candidates,
                                                  Point2 at, double reach_mm) {
    std::optional<NearestCandidate> nearest;
    double best = reach_mm;
    for (std::size_t k = 0; k < candidates.size(); ++k) {
        const double e =
            std::hypot(candidates[k].machine_mm.x - at.x, candidates[k].machine_mm.y - at.y);
        if (e < best) best = e, nearest = NearestCandidate{k, e};
    }
    return nearest;
}

std::vector<MarkMatching> matchings_of(const std::vector<Candidate>& candidates,
                                       const std::vector<Point2>& marks, double base,
                                       double reach_mm) {
    std::vector<MarkMatching> matchings;
    for (std::size_t a = 0; a < candidates.size(); ++a)
        for (std::size_t b = 0; b < candidates.size(); ++b) {
            if (a == b) continue;
            const Point2 ca = candidates[a].machine_mm, cb = candidates[b].machine_mm;
            if (std::abs(std::hypot(cb.x - ca.x, cb.y - ca.y) - base) > reach_mm) continue;
            const double turn = std::atan2(cb.y - ca.y, cb.x - ca.x) -
                                std::atan2(marks[1].y - marks[0].y, marks[1].x - marks[0].x);
            const double c = std::cos(turn), s = std::sin(turn);
            MarkMatching m;
            m.rotation_rad = turn;
            m.candidate_of_mark = {a, b};
            bool all = true;
            for (std::size_t i = 2; i < marks.size(); ++i) {
                const Point2 d{marks[i].x - marks[0].x, marks[i].y - marks[0].y};
                const Point2 predicted{ca.x + c * d.x - s * d.y, ca.y + s * d.x + c * d.y};
                const auto nearest = nearest_candidate(candidates, predicted, reach_mm);
                all = nearest.has_value();
                if (!nearest) break;
                m.candidate_of_mark.push_back(nearest->index);
                m.misfit_mm += nearest->distance_mm;
            }
            if (all) matchings.push_back(m);
        }
    return matchings;
}

// The circles or crosses: the photo's marks of the printed size and shape, and the one way the
// drawing's marks lie on them. A cross's centroid is its centre as a disc's is: both are
// symmetric about it, and the moment window around it is too.
std::pair<std::vector<Point2>, std::vector<double>> printed_marks(
    const geometry::CameraModel& camera, const geometry::BedPlane& plane,
    const vision::GrayView& photo, const BedToMachine& map, const RegistrationRequest& request,
    double px_per_mm) {
    const auto& marks = request.marks_drawing_mm;
    const std::string what = request.kind == MarkKind::crosses ? "crosses" : "round marks";
    const std::vector<Candidate> candidates =
        mark_candidates(camera, plane, photo, map, request, px_per_mm);

    // A printer's stretch of a percent or two and the photo's millimetre leave room.
    const double base = std::hypot(marks[1].x - marks[0].x, marks[1].y - marks[0].y);
    const double reach_mm = 0.02 * base + 1.0;
    std::vector<MarkMatching> matchings = matchings_of(candidates, marks, base, reach_mm);
    if (matchings.empty())
        throw RegistrationError("no " + std::to_string(candidates.size()) + " " + what +
                                " in the photo lie as the drawing's " +
                                std::to_string(marks.size()) + " do (within " +
                                number_text("%.1f", reach_mm) + " mm)");
    std::sort(matchings.begin(), matchings.end(), [](const MarkMatching& x, const MarkMatching& y) {
        return x.misfit_mm < y.misfit_mm;
    });
    // Two ways of laying the marks that fit alike and turn the drawing differently: a symmetric
    // layout, and nothing tells which way round the drawing lies.
    for (std::size_t k = 1; k < matchings.size(); ++k) {
        double apart = std::remainder(matchings[k].rotation_rad - matchings[0].rotation_rad,
                                      2 * std::numbers::pi);
        if (std::abs(apart) > 1 * std::numbers::pi / 180 && matchings[k].misfit_mm < 2 * reach_mm)
            throw RegistrationError("the marks lie symmetrically: the drawing fits them turned " +
                                    number_text("%.0f", std::abs(apart) * 180 / std::numbers::pi) +
                                    " degrees apart too; print them off symmetry (one mark moved)");
    }
    const auto& best = matchings.front();
    std::vector<Point2> seen;
    std::vector<double> sigma;
    for (const std::size_t k : best.candidate_of_mark) {
        seen.push_back(candidates[k].machine_mm);
        sigma.push_back(candidates[k].sigma_mm);
    }
    return {seen, sigma};
}

}  // namespace

namespace {

// The drawing's place fitted to its marks as seen; each mark's residual, the limits checked.
Registration fitted_registration(const std::vector<Point2>& marks, const std::vector<Point2>& seen,
                                 const std::vector<double>& sigma,
                                 const RegistrationRequest& request) {
    Registration r;
    r.surface_height_mm = request.surface_height_mm;
    r.scale_fitted = marks.size() == 4;
    geometry::SimilarPlacement fit;
    if (r.scale_fitted) {
        fit = geometry::best_similar_placement(marks, seen);
    } else {
        const auto rigid = geometry::best_rigid_placement(marks, seen);
        fit.angle_rad = rigid.angle_rad;
        fit.translation_mm = rigid.translation_mm;
    }
    r.origin_mm = fit.translation_mm;
    r.rotation_deg = std::remainder(fit.angle_rad, 2 * std::numbers::pi) * 180 / std::numbers::pi;
    r.scale = fit.scale;
    for (std::size_t i = 0; i < marks.size(); ++i) {
        const Point2 placed = fit.apply(marks[i]);
        RegisteredMark m;
        m.drawing_mm = marks[i];
        m.machine_mm = seen[i];
        m.residual_mm = std::hypot(seen[i].x - placed.x, seen[i].y - placed.y);
        m.sigma_mm = sigma[i];
        r.worst_residual_mm = std::max(r.worst_residual_mm, m.residual_mm);
        r.marks.push_back(m);
    }
    for (std::size_t i = 0; i < r.marks.size(); ++i)
        if (r.marks[i].residual_mm > request.max_residual_mm)
            throw RegistrationError("mark " + std::to_string(i + 1) + " (drawing " +
                                    drawing_text(marks[i]) + ") lies " +
                                    number_text("%.3f", r.marks[i].residual_mm) +
                                    " mm from where the others put it, "
                                    "over " +
                                    number_text("%.3f", request.max_residual_mm) +
                                    " mm: a misprint, a smudge, or the sheet not flat");
    if (r.scale_fitted && std::abs(r.scale - 1) > 0.03)
        throw RegistrationError("the marks lie " + number_text("%.2f", 100 * (r.scale - 1)) +
                                " % larger than the drawing's: another drawing, or printed at "
                                "another size");
    return r;
}

}  // namespace

namespace {

// The request's marks and their size: three or four, 0.5 to 50 mm across, crosses' bars a tenth
// of a millimetre to a quarter of their span, the marks three diameters apart at the least.
void check_registration_request(const RegistrationRequest& request) {
    const auto& marks = request.marks_drawing_mm;
    if (marks.size() != 3 && marks.size() != 4)
        throw RegistrationError(std::to_string(marks.size()) +
                                " registration marks given: print and cut takes three or four");
    if (!(request.mark_diameter_mm > 0.5 && request.mark_diameter_mm < 50))
        throw RegistrationError("a mark " + number_text("%.2f", request.mark_diameter_mm) +
                                " mm across: give 0.5 to 50 mm");
    if (request.kind == MarkKind::crosses &&
        !(request.cross_line_mm >= 0.1 && request.cross_line_mm <= request.mark_diameter_mm / 4))
        throw RegistrationError("crosses with bars " + number_text("%.2f", request.cross_line_mm) +
                                " mm wide: give 0.1 mm to a quarter of their " +
                                number_text("%.2f", request.mark_diameter_mm) + " mm span");
    for (std::size_t i = 0; i < marks.size(); ++i)
        for (std::size_t j = i + 1; j < marks.size(); ++j)
            if (std::hypot(marks[i].x - marks[j].x, marks[i].y - marks[j].y) <
                3 * request.mark_diameter_mm)
                throw RegistrationError("marks " + std::to_string(i + 1) + " and " +
                                        std::to_string(j + 1) +
                                        " lie under three diameters apart: they blur together");
}

// Each marker mark's centre on the machine, found by its id, and its uncertainty (mm).
std::pair<std::vector<Point2>, std::vector<double>> marker_marks(
    const geometry::CameraModel& camera, const geometry::BedPlane& plane,
    const vision::GrayView& photo, const BedToMachine& map, const RegistrationRequest& request,
    double px_per_mm) {
    const auto& marks = request.marks_drawing_mm;
    const double h = request.surface_height_mm;
    std::vector<Point2> seen;
    std::vector<double> seen_sigma;
    if (request.marker_ids.size() != marks.size())
        throw RegistrationError(
            "each marker mark needs its id: " + std::to_string(request.marker_ids.size()) +
            " ids for " + std::to_string(marks.size()) + " marks");
    vision::MarkerOptions options;
    options.dictionary = request.dictionary;
    options.camera = &camera;
    const auto detected = vision::detect_markers(photo, options);
    for (std::size_t i = 0; i < marks.size(); ++i) {
        const auto found = std::find_if(detected.begin(), detected.end(), [&](const auto& d) {
            return d.id == request.marker_ids[i];
        });
        if (found == detected.end())
            throw RegistrationError("marker " + std::to_string(request.marker_ids[i]) + " (" +
                                    request.dictionary + ", drawing " + drawing_text(marks[i]) +
                                    ") is not in the photo");
        // The marker's centre on the sheet: its diagonals' crossing there (the photo's
        // perspective moves the centre of its outline in pixels).
        const auto corners = geometry::pixels_to_bed(
            camera, plane, {found->corners.begin(), found->corners.end()}, h);
        std::vector<Point2> on_machine;
        on_machine.reserve(corners.size());
        for (const auto& c : corners) on_machine.push_back(map.machine_of({c.x, c.y}));
        const auto centre = geometry::intersect(
            {on_machine[0], {on_machine[2].x - on_machine[0].x, on_machine[2].y - on_machine[0].y}},
            {on_machine[1],
             {on_machine[3].x - on_machine[1].x, on_machine[3].y - on_machine[1].y}});
        if (!centre)
            throw RegistrationError("marker " + std::to_string(request.marker_ids[i]) +
                                    " has no centre: its corners lie on a line");
        seen.push_back(*centre);
        double sigma_px = 0;
        for (const double sp : found->sigma_px) sigma_px += sp / 4;
        seen_sigma.push_back(sigma_px / px_per_mm / std::sqrt(2.0));
    }
    return {seen, seen_sigma};
}

}  // namespace

Registration register_marks(const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                            const vision::GrayView& photo, const PlanarSolution& solution,
                            const RegistrationRequest& request, const std::string& source) {
    const auto& marks = request.marks_drawing_mm;
    check_registration_request(request);
    const BedToMachine map = photo_on_machine(camera, photo, solution, source);
    const double h = request.surface_height_mm;

    // The photo's scale at its middle, for the marks' size there.
    const auto middle = geometry::pixels_to_bed(
        camera, plane, {{0.5 * (photo.width_px - 1), 0.5 * (photo.height_px - 1)}}, h)[0];
    const double px_per_mm = photo_px_per_mm(camera, plane, middle, {middle.x + 1, middle.y, h},
                                             {middle.x, middle.y + 1, h});
    const auto [seen, seen_sigma] =
        request.kind == MarkKind::markers
            ? marker_marks(camera, plane, photo, map, request, px_per_mm)
            : printed_marks(camera, plane, photo, map, request, px_per_mm);
    return fitted_registration(marks, seen, seen_sigma, request);
}

std::string registration_to_json(const Registration& r, const std::string& machine_fingerprint) {
    using nlohmann::json;
    json marks = json::array();
    for (const auto& m : r.marks)
        marks.push_back({{"drawing_mm", point_json(m.drawing_mm)},
                         {"machine_mm", point_json(m.machine_mm)},
                         {"residual_mm", m.residual_mm},
                         {"sigma_mm", m.sigma_mm}});
    const json j{{"schema", kRegistrationSchema},
                 {"machine_fingerprint", machine_fingerprint},
                 {"origin_mm", point_json(r.origin_mm)},
                 {"rotation_deg", r.rotation_deg},
                 {"scale", r.scale},
                 {"scale_fitted", r.scale_fitted},
                 {"worst_residual_mm", r.worst_residual_mm},
                 {"surface_height_mm", r.surface_height_mm},
                 {"marks", marks}};
    return j.dump(1) + "\n";
}

RegistrationRecord registration_from_json(const std::string& text, const std::string& source) {
    const auto j = parse_record(text, source, kRegistrationSchema, "registration");
    try {
        RegistrationRecord rec;
        auto& r = rec.registration;
        rec.machine_fingerprint = j.at("machine_fingerprint").get<std::string>();
        r.origin_mm = point_from(j.at("origin_mm"));
        r.rotation_deg = j.at("rotation_deg").get<double>();
        r.scale = j.at("scale").get<double>();
        r.scale_fitted = j.at("scale_fitted").get<bool>();
        r.worst_residual_mm = j.at("worst_residual_mm").get<double>();
        r.surface_height_mm = j.at("surface_height_mm").get<double>();
        if (!std::isfinite(r.origin_mm.x) || !std::isfinite(r.origin_mm.y) ||
            !(std::abs(r.rotation_deg) <= 180) || !(r.scale > 0.9 && r.scale < 1.1))
            throw RecordError(source +
                              ": the drawing's place (origin, rotation within 180, "
                              "scale within 10 %) is out of bounds");
        for (const auto& m : j.at("marks"))
            r.marks.push_back({point_from(m.at("drawing_mm")), point_from(m.at("machine_mm")),
                               m.at("residual_mm").get<double>(), m.at("sigma_mm").get<double>()});
        return rec;
    } catch (const nlohmann::json::exception& e) {
        throw RecordError(source + ": malformed registration file: " + e.what());
    }
}

}  // namespace calbox::modes
