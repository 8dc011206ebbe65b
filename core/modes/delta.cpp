#include "core/modes/delta.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

namespace calbox::modes {
namespace {

// Exposure that leaves no edge to measure: most of the frame clipped, or no contrast at all.
void check_exposure(const vision::GrayView& image, std::size_t frame) {
    std::array<std::size_t, 256> histogram{};
    for (int y = 0; y < image.height_px; y += 2)
        for (int x = 0; x < image.width_px; x += 2) ++histogram[image.at(x, y)];
    std::size_t total = 0, clipped = 0;
    int brightest = 0;
    for (int v = 0; v < 256; ++v) {
        total += histogram[static_cast<std::size_t>(v)];
        if (v >= 250) clipped += histogram[static_cast<std::size_t>(v)];
        if (histogram[static_cast<std::size_t>(v)] > 0) brightest = v;
    }
    const std::string which = "photo " + std::to_string(frame + 1);
    if (clipped * 5 > total)
        throw MeasureError(which + " is over-exposed: " + std::to_string(100 * clipped / total) +
                           " % of it is clipped white");
    if (brightest < 60)
        throw MeasureError(which + " is under-exposed: nothing in it is brighter than " +
                           std::to_string(brightest) + " of 255");
}

}  // namespace

DeltaMeasurement measure_delta(const models::MachineFile& machine,
                               const geometry::CameraModel& camera, const geometry::BedPlane& plane,
                               const std::vector<vision::GrayView>& frames) {
    if (frames.empty()) throw MeasureError("no photos to measure");
    DeltaMeasurement out;
    out.target = targets::make_delta_target(machine);  // regenerated: generation is deterministic
    const auto& markers = out.target.markers;
    vision::MarkerOptions options;
    options.camera = &camera;
    // Per corner: the sum of its bed positions over the frames that saw it.
    std::map<std::pair<int, int>, std::vector<geometry::Point3>> seen;
    std::map<std::pair<int, int>, geometry::Point2> shift;  // bed mm per mm of height along the ray
    for (std::size_t f = 0; f < frames.size(); ++f) {
        const auto& frame = frames[f];
        if (frame.width_px != camera.image_width || frame.height_px != camera.image_height) {
            throw MeasureError(
                "photo " + std::to_string(f + 1) + " is " + std::to_string(frame.width_px) + "x" +
                std::to_string(frame.height_px) + ", the camera was calibrated at " +
                std::to_string(camera.image_width) + "x" + std::to_string(camera.image_height));
        }
        check_exposure(frame, f);
        auto found = vision::detect_markers(frame, options);
        if (found.empty())
            throw MeasureError("photo " + std::to_string(f + 1) + " shows no " +
                               options.dictionary + " markers");
        const auto foreign = std::count_if(found.begin(), found.end(), [&](const auto& m) {
            return m.id >= static_cast<int>(markers.size());
        });
        if (foreign * 2 > static_cast<long>(found.size())) {
            throw MeasureError("photo " + std::to_string(f + 1) +
                               " shows markers that are not this machine's delta target");
        }
        found.erase(
            std::remove_if(found.begin(), found.end(),
                           [&](const auto& m) { return m.id >= static_cast<int>(markers.size()); }),
            found.end());
        if (found.size() * 2 < markers.size()) {
            throw MeasureError("photo " + std::to_string(f + 1) + " shows " +
                               std::to_string(found.size()) + " of the target's " +
                               std::to_string(markers.size()) +
                               " markers: the artifact is partly out of frame");
        }
        for (const auto& m : found) {
            std::vector<geometry::Point2> corners(m.corners.begin(), m.corners.end());
            const auto bed =
                geometry::pixels_to_bed(camera, plane, corners, out.target.top_height_mm);
            const auto above =
                geometry::pixels_to_bed(camera, plane, corners, out.target.top_height_mm + 1);
            for (std::size_t k = 0; k < 4; ++k) {
                seen[{m.id, static_cast<int>(k)}].push_back(bed[k]);
                shift[{m.id, static_cast<int>(k)}] = {above[k].x - bed[k].x, above[k].y - bed[k].y};
            }
        }
        out.frames.push_back(std::move(found));
    }
    // A printed corner's position from one 12 MP frame is good to about 0.005 mm; several frames
    // average, and their scatter is used when it is larger.
    constexpr double kSingleFrameSigmaMm = 0.005;
    for (const auto& [key, points] : seen) {
        const auto& target_corner = markers[static_cast<std::size_t>(key.first)]
                                        .corners_mm[static_cast<std::size_t>(key.second)];
        double mx = 0, my = 0;
        for (const auto& p : points) mx += p.x, my += p.y;
        const double n = static_cast<double>(points.size());
        mx /= n, my /= n;
        double scatter = 0;
        for (const auto& p : points) scatter += (p.x - mx) * (p.x - mx) + (p.y - my) * (p.y - my);
        const double sigma =
            std::max(kSingleFrameSigmaMm, n > 1 ? std::sqrt(scatter / (2 * (n - 1))) : 0.0) /
            std::sqrt(n);
        out.features.push_back({"m" + std::to_string(key.first) + "c" + std::to_string(key.second),
                                {target_corner.x, target_corner.y, out.target.top_height_mm},
                                {mx, my},
                                sigma,
                                out.target.top_height_mm,
                                shift[key]});
    }
    return out;
}

}  // namespace calbox::modes
