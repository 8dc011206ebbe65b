#include "core/modes/error_through.hpp"

#include <stdexcept>

#include "core/geometry/placement.hpp"
#include "core/models/galvo_field.hpp"

namespace calbox::modes {

using geometry::Point2;

ErrorFigures error_through(const std::vector<Point2>& commanded_mm,
                           const std::vector<Point2>& error_mm, const jobs::KeptCorrection& kept,
                           const jobs::Correction& error_field) {
    if (commanded_mm.size() != error_mm.size() || commanded_mm.size() < 3)
        throw std::invalid_argument(
            "the error through a correction needs as many errors as points, at least three");
    const jobs::Area kept_area{kept.min_x_mm, kept.min_y_mm, kept.max_x_mm, kept.max_y_mm};
    std::vector<Point2> meant, landed;
    meant.reserve(commanded_mm.size());
    landed.reserve(commanded_mm.size());
    for (std::size_t i = 0; i < commanded_mm.size(); ++i) {
        const Point2 p = commanded_mm[i];
        const Point2 held = kept_area.nearest(p);
        const Point2 kept_command = kept.correct(held);
        const Point2 command{p.x + kept_command.x - held.x, p.y + kept_command.y - held.y};
        Point2 error = error_mm[i];
        if (error_field) {
            const Point2 there = error_field(command), here = error_field(p);
            error = {error.x + there.x - here.x, error.y + there.y - here.y};
        }
        meant.push_back(p);
        landed.push_back({command.x + error.x, command.y + error.y});
    }
    const auto placement = geometry::best_rigid_placement(landed, meant);
    std::vector<Point2> residuals;
    residuals.reserve(meant.size());
    for (std::size_t i = 0; i < meant.size(); ++i) {
        const Point2 at = placement.apply(landed[i]);
        residuals.push_back({at.x - meant[i].x, at.y - meant[i].y});
    }
    const auto s = models::error_statistics(residuals);
    return {s.mean_mm, s.rms_mm, s.max_mm};
}

}  // namespace calbox::modes
