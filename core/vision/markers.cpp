#include "core/vision/markers.hpp"

#include <apriltag/apriltag.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <opencv2/core/version.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "core/each_on_all_cores.hpp"
#include "core/geometry/cv_convert.hpp"
#include "core/geometry/line_fit.hpp"
#include "core/geometry/pattern_spec.hpp"
#include "core/number_text.hpp"
#include "core/vision/edge_kernel.hpp"

#if CV_VERSION_MAJOR > 4 || (CV_VERSION_MAJOR == 4 && CV_VERSION_MINOR >= 7)
#include <opencv2/objdetect/aruco_detector.hpp>
#define CALBOX_ARUCO_DETECTOR_API 1
#else
#include <opencv2/aruco.hpp>
#define CALBOX_ARUCO_DETECTOR_API 0
#endif

namespace calbox::vision {
namespace {

using geometry::fit_line;
using geometry::intersect;
using geometry::Line;
using geometry::Point2;

struct RawMarkers {
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    int cells_per_side = 0;   // of the square whose outline was found
    bool dark_inside = true;  // that square's border: black inside a white zone, or reversed
};

// The adapter: OpenCV 4.7 moved ArUco into objdetect with a detector object.
RawMarkers opencv_detect(const cv::Mat& gray, int dictionary_id, double smallest_side_px) {
    RawMarkers raw;
    const auto set = [&](cv::aruco::DetectorParameters& parameters) {
        parameters.cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
        if (smallest_side_px > 0) {
            parameters.useAruco3Detection = true;
            parameters.minMarkerLengthRatioOriginalImg =
                static_cast<float>(smallest_side_px / std::max(gray.cols, gray.rows));
        }
    };
#if CALBOX_ARUCO_DETECTOR_API
    const cv::aruco::Dictionary dictionary = cv::aruco::getPredefinedDictionary(dictionary_id);
    cv::aruco::DetectorParameters parameters;
    set(parameters);
    cv::aruco::ArucoDetector(dictionary, parameters).detectMarkers(gray, raw.corners, raw.ids);
    raw.cells_per_side = dictionary.markerSize + 2;
#else
    const auto dictionary = cv::aruco::getPredefinedDictionary(dictionary_id);
    const auto parameters = cv::aruco::DetectorParameters::create();
    set(*parameters);
    cv::aruco::detectMarkers(gray, dictionary, raw.corners, raw.ids, parameters);
    raw.cells_per_side = dictionary->markerSize + 2;
#endif
    return raw;
}

// libapriltag's families (AprilTag 3), by the names its own tools use. OpenCV draws its
// DICT_APRILTAG_36h11 and 25h9 markers turned half round from AprilTag's own images of the same
// codes; the corners are numbered as OpenCV numbers its drawing, so that a target drawn by
// either library has the same corner 0 whichever detector reads it. A family OpenCV lacks is
// numbered as AprilTag draws it: clockwise from its top-left.
struct AprilTagFamily {
    const char* name;
    apriltag_family_t* (*create)();
    void (*destroy)(apriltag_family_t*);
    bool turned_in_opencv;
};
constexpr std::array<AprilTagFamily, 3> kAprilTagFamilies{{
    {"tag36h11", tag36h11_create, tag36h11_destroy, true},
    {"tag25h9", tag25h9_create, tag25h9_destroy, true},
    {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy, false},
}};

const AprilTagFamily* apriltag_family(const std::string& name) {
    for (const auto& f : kAprilTagFamilies)
        if (name == f.name) return &f;
    return nullptr;
}

// The libapriltag family with the codes of one of OpenCV's AprilTag dictionaries, or null.
const AprilTagFamily* apriltag_family_of_opencv(const std::string& dictionary) {
    if (dictionary == "DICT_APRILTAG_36h11") return apriltag_family("tag36h11");
    if (dictionary == "DICT_APRILTAG_25h9") return apriltag_family("tag25h9");
    return nullptr;
}

RawMarkers apriltag_detect(const GrayView& image, const AprilTagFamily& which,
                           const AprilTagLimits& limits) {
    const std::unique_ptr<apriltag_family_t, void (*)(apriltag_family_t*)> family(which.create(),
                                                                                  which.destroy);
    const std::unique_ptr<apriltag_detector_t, void (*)(apriltag_detector_t*)> detector(
        apriltag_detector_create(), apriltag_detector_destroy);
    if (!family || !detector) throw std::bad_alloc();
    apriltag_detector_add_family_bits(detector.get(), family.get(), limits.bits_corrected);
    detector->quad_decimate = limits.quad_decimate;
    detector->nthreads = 2;
    detector->refine_edges = true;
    // The detector takes a mutable image but only reads it.
    image_u8_t view{image.width_px, image.height_px, image.stride_bytes,
                    const_cast<std::uint8_t*>(image.pixels)};
    const std::unique_ptr<zarray_t, void (*)(zarray_t*)> found(
        apriltag_detector_detect(detector.get(), &view), apriltag_detections_destroy);
    RawMarkers raw;
    raw.cells_per_side = family->width_at_border;
    raw.dark_inside = !family->reversed_border;
    for (int i = 0; i < zarray_size(found.get()); ++i) {
        apriltag_detection_t* d = nullptr;
        zarray_get(found.get(), i, &d);
        if (d->decision_margin < limits.min_decision_margin) continue;
        raw.ids.push_back(d->id);
        // AprilTag's corners run the other way round from its image's bottom-left.
        std::vector<cv::Point2f> corners;
        for (const int k : which.turned_in_opencv ? std::array{1, 0, 3, 2} : std::array{3, 2, 1, 0})
            corners.emplace_back(static_cast<float>(d->p[k][0]), static_cast<float>(d->p[k][1]));
        raw.corners.push_back(std::move(corners));
    }
    return raw;
}

// Edge points along the side from p to q (clockwise order: the marker lies to the right).
std::vector<Point2> edge_points(const GrayView& image, Point2 p, Point2 q, int cells_per_side,
                                bool dark_inside, const MarkerRefineLimits& limits) {
    const double length = std::hypot(q.x - p.x, q.y - p.y);
    std::vector<Point2> out;
    if (length < 8) return out;
    const Point2 d{(q.x - p.x) / length, (q.y - p.y) / length};
    const Point2 outward{d.y, -d.x};
    const double half = std::clamp(limits.profile_reach_cells * length / cells_per_side,
                                   limits.profile_reach_min_px, limits.profile_reach_max_px);
    const double margin = std::max(limits.corner_clearance_share * length, half + 1.0);
    // Profiles every half pixel along the edge, clear of its corners.
    const int profiles = static_cast<int>((length - 2 * margin) / 0.5) + 1;
    for (int i = 0; i < profiles; ++i) {
        const double t = margin + 0.5 * i;
        const Point2 on{p.x + d.x * t, p.y + d.y * t};
        const auto edge =
            step_edge_on_segment(image, {on.x - outward.x * half, on.y - outward.y * half},
                                 {on.x + outward.x * half, on.y + outward.y * half}, dark_inside);
        if (edge) out.push_back(*edge);
    }
    return out;
}

}  // namespace

RefinedCorners refine_marker_corners(const GrayView& image, const std::array<Point2, 4>& rough,
                                     int cells_per_side, const geometry::CameraModel* camera,
                                     const MarkerRefineLimits& limits, bool dark_inside) {
    static constexpr std::array<const char*, 4> kEdgeNames = {"top", "right", "bottom", "left"};
    const auto kept = [&](std::string why) {
        const double s = limits.unrefined_corner_sigma_px;
        return RefinedCorners{rough, false, std::move(why), {s, s, s, s}};
    };
    // Edge profiles are taken every half pixel and each reads a 2x2 neighbourhood: only every
    // second one carries noise of its own.
    constexpr double kIndependentProfileShare = 0.5;
    std::array<std::vector<Point2>, 4> edges;
    std::array<Line, 4> lines;
    std::vector<Point2> fitted_corners;  // in the edges' coordinates (normalised with a camera)
    std::array<Point2, 4> corners = rough;
    for (int pass = 0; pass < 2; ++pass) {
        for (std::size_t k = 0; k < 4; ++k) {
            auto& points = edges[k];
            points = edge_points(image, corners[k], corners[(k + 1) % 4], cells_per_side,
                                 dark_inside, limits);
            if (points.size() < limits.min_edge_points) {
                return kept(std::string("the ") + kEdgeNames[k] + " edge gave " +
                            std::to_string(points.size()) + " points (at least " +
                            std::to_string(limits.min_edge_points) + " needed)");
            }
            if (camera != nullptr) points = geometry::undistort_to_normalized(*camera, points);
            lines[k] = fit_line(points);
        }
        fitted_corners.clear();
        for (std::size_t k = 0; k < 4; ++k) {
            const auto c = intersect(lines[(k + 3) % 4], lines[k]);
            if (!c) return kept("two edges fitted parallel");
            fitted_corners.push_back(*c);
        }
        auto refined = camera != nullptr
                           ? geometry::distort_from_normalized(*camera, fitted_corners)
                           : fitted_corners;
        for (std::size_t k = 0; k < 4; ++k) {
            const double moved = std::hypot(refined[k].x - rough[k].x, refined[k].y - rough[k].y);
            if (moved > limits.max_corner_move_px) {
                return kept("corner " + std::to_string(k) + " moved " + number_text("%.1f", moved) +
                            " px from OpenCV's (at most " +
                            number_text("%.1f", limits.max_corner_move_px) + ")");
            }
            corners[k] = refined[k];
        }
    }
    // A corner moves with either edge's offset across it: per coordinate, the two offsets'
    // RMS over the sine of the angle between the edges.
    const double pixels_per_unit = camera != nullptr ? camera->fx() : 1.0;
    std::array<double, 4> sigma_px{};
    for (std::size_t k = 0; k < 4; ++k) {
        const auto& a = lines[(k + 3) % 4];
        const auto& b = lines[k];
        const double sa = geometry::line_sigma_at(a, edges[(k + 3) % 4], fitted_corners[k],
                                                  kIndependentProfileShare);
        const double sb =
            geometry::line_sigma_at(b, edges[k], fitted_corners[k], kIndependentProfileShare);
        const double sine = std::abs(a.direction.x * b.direction.y - a.direction.y * b.direction.x);
        sigma_px[k] = pixels_per_unit * std::sqrt((sa * sa + sb * sb) / 2) / sine;
    }
    return {corners, true, {}, sigma_px};
}

namespace {

// Adds `more`'s marks whose ids `raw` lacks.
void add_missing(RawMarkers& raw, const RawMarkers& more) {
    for (std::size_t m = 0; m < more.ids.size(); ++m)
        if (std::find(raw.ids.begin(), raw.ids.end(), more.ids[m]) == raw.ids.end()) {
            raw.ids.push_back(more.ids[m]);
            raw.corners.push_back(more.corners[m]);
        }
}

// Whether `raw` holds every one of `wanted` (false when nothing is wanted: every look is taken).
bool holds_all(const RawMarkers& raw, const std::vector<int>& wanted) {
    return !wanted.empty() && std::all_of(wanted.begin(), wanted.end(), [&](int id) {
        return std::find(raw.ids.begin(), raw.ids.end(), id) != raw.ids.end();
    });
}

// The detectors' rough finds in one image, each id once; the later looks left out once the first
// has found every one of `wanted`.
RawMarkers detect_raw(const GrayView& image, const MarkerOptions& options,
                      const std::vector<int>& wanted) {
    const AprilTagFamily* family = apriltag_family(options.dictionary);
    RawMarkers raw;
    if (family != nullptr) {
        raw = apriltag_detect(image, *family, options.apriltag_limits);
        if (holds_all(raw, wanted)) return raw;
        if (options.apriltag_limits.second_pass_decimate > 0 &&
            options.apriltag_limits.second_pass_decimate != options.apriltag_limits.quad_decimate) {
            AprilTagLimits second = options.apriltag_limits;
            second.quad_decimate = options.apriltag_limits.second_pass_decimate;
            add_missing(raw, apriltag_detect(image, *family, second));
        }
        return raw;
    }
    int dictionary_id = 0;
    try {
        dictionary_id = geometry::aruco_dictionary_id(options.dictionary);
    } catch (const geometry::PatternError&) {
        throw geometry::PatternError(
            "unknown marker dictionary '" + options.dictionary +
            "' (OpenCV's DICT_4X4_50 ... DICT_7X7_1000, DICT_ARUCO_ORIGINAL, "
            "DICT_APRILTAG_36h11, or libapriltag's tag36h11, tag25h9, tagStandard41h12)");
    }
    raw = opencv_detect(geometry::to_cv(image), dictionary_id, options.smallest_side_px);
    if (holds_all(raw, wanted)) return raw;
    // OpenCV's AprilTag dictionaries are AprilTag's codes, which libapriltag reads too, and
    // through a blur that loses OpenCV's quads (a lens's soft corners, where the reference marks
    // stand). Its finds add the marks OpenCV missed; those OpenCV found stay as they were.
    if (const AprilTagFamily* same_codes = apriltag_family_of_opencv(options.dictionary))
        add_missing(raw, apriltag_detect(image, *same_codes, options.apriltag_limits));
    return raw;
}

// The detectors' finds in one image (or window), with the equalised second look if asked.
RawMarkers detect_raw_with_equalized(const GrayView& image, const MarkerOptions& options,
                                     const std::vector<int>& wanted = {}) {
    RawMarkers raw = detect_raw(image, options, wanted);
    if (options.equalized_pass && !holds_all(raw, wanted)) {
        // Marks in a dim corner (light falling off, a vignette) under a soft lens: equalised tile
        // by tile their cells show again. Found there, they are refined on the photo itself.
        cv::Mat equalized;
        cv::createCLAHE(options.equalize_clip_limit,
                        cv::Size(options.equalize_tiles, options.equalize_tiles))
            ->apply(geometry::to_cv(image), equalized);
        add_missing(raw, detect_raw(GrayView{equalized.data, equalized.cols, equalized.rows,
                                             static_cast<int>(equalized.step)},
                                    options, wanted));
    }
    return raw;
}

// The finds in each window (a view into the image, no copy), their corners in the image's pixels.
RawMarkers detect_raw_in_windows(const GrayView& image, const MarkerOptions& options) {
    RawMarkers raw;
    for (const auto& w : options.windows) {
        const int x0 = std::clamp(w.x_px, 0, image.width_px);
        const int y0 = std::clamp(w.y_px, 0, image.height_px);
        const int x1 = std::clamp(w.x_px + w.width_px, x0, image.width_px);
        const int y1 = std::clamp(w.y_px + w.height_px, y0, image.height_px);
        if (x1 - x0 < 8 || y1 - y0 < 8) continue;  // nothing a marker fits in
        const GrayView window{image.pixels + static_cast<long>(y0) * image.stride_bytes + x0,
                              x1 - x0, y1 - y0, image.stride_bytes};
        RawMarkers found = detect_raw_with_equalized(window, options, w.wanted_ids);
        for (auto& corners : found.corners)
            for (auto& c : corners)
                c += cv::Point2f(static_cast<float>(x0), static_cast<float>(y0));
        raw.cells_per_side = found.cells_per_side;
        raw.dark_inside = found.dark_inside;
        add_missing(raw, found);
    }
    return raw;
}

}  // namespace

std::vector<DetectedMarker> detect_markers(const GrayView& image, const MarkerOptions& options) {
    RawMarkers raw = options.windows.empty() ? detect_raw_with_equalized(image, options)
                                             : detect_raw_in_windows(image, options);
    const bool a_wanted_mark_missed =
        std::any_of(options.windows.begin(), options.windows.end(), [&](const PixelWindow& w) {
            return !w.wanted_ids.empty() && !holds_all(raw, w.wanted_ids);
        });
    if (a_wanted_mark_missed) {
        MarkerOptions whole = options;
        whole.windows.clear();
        whole.smallest_side_px = 0;
        raw = detect_raw_with_equalized(image, whole);
    }
    // Each marker's corners refined on its own (the image and the camera only read), on all cores.
    std::vector<DetectedMarker> out(raw.ids.size());
    each_on_all_cores(raw.ids.size(), [&](std::size_t m) {
        DetectedMarker& marker = out[m];
        marker.id = raw.ids[m];
        for (int k = 0; k < 4; ++k) {
            marker.corners[static_cast<std::size_t>(k)] = {
                raw.corners[m][static_cast<std::size_t>(k)].x,
                raw.corners[m][static_cast<std::size_t>(k)].y};
        }
        if (options.refine_edges) {
            static_cast<RefinedCorners&>(marker) =
                refine_marker_corners(image, marker.corners, raw.cells_per_side, options.camera,
                                      options.refine_limits, raw.dark_inside);
        } else {
            marker.unrefined_because = "refinement off";
            marker.sigma_px.fill(options.refine_limits.unrefined_corner_sigma_px);
        }
    });
    std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
    return out;
}

}  // namespace calbox::vision
