#include "core/vision/reference_marks.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/core.hpp>

namespace calbox::vision {

namespace {

// How the marks are looked for, wherever: they stand near the view's corners, where the light is
// least and a lens softest.
MarkerOptions reference_options(const std::string& dictionary,
                                const geometry::CameraModel& camera) {
    MarkerOptions options;
    options.dictionary = dictionary;
    options.camera = &camera;
    options.equalized_pass = true;
    return options;
}

}  // namespace

ReferenceView find_reference_marks(const GrayView& image, const std::string& dictionary,
                                   const geometry::CameraModel& camera) {
    return {dictionary, detect_markers(image, reference_options(dictionary, camera))};
}

ReferenceView find_reference_marks_again(const GrayView& image, const ReferenceView& stored,
                                         const geometry::CameraModel& camera) {
    MarkerOptions options = reference_options(stored.dictionary, camera);
    for (const auto& mark : stored.marks) {
        double x0 = mark.corners[0].x, x1 = x0, y0 = mark.corners[0].y, y1 = y0;
        for (const auto& c : mark.corners) {
            x0 = std::min(x0, c.x), x1 = std::max(x1, c.x);
            y0 = std::min(y0, c.y), y1 = std::max(y1, c.y);
        }
        const double grow = std::max(x1 - x0, y1 - y0);
        options.windows.push_back({static_cast<int>(std::floor(x0 - grow)),
                                   static_cast<int>(std::floor(y0 - grow)),
                                   static_cast<int>(std::ceil(x1 - x0 + 2 * grow)),
                                   static_cast<int>(std::ceil(y1 - y0 + 2 * grow)),
                                   {mark.id}});
    }
    return {stored.dictionary, detect_markers(image, options)};
}

std::string reference_to_yaml(const ReferenceView& view) {
    cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    fs << "dictionary" << view.dictionary;
    fs << "marks"
       << "[";
    for (const auto& m : view.marks) {
        fs << "{"
           << "id" << m.id << "corners"
           << "[";
        for (const auto& c : m.corners) fs << c.x << c.y;
        fs << "]"
           << "}";
    }
    fs << "]";
    return fs.releaseAndGetString();
}

ReferenceView reference_from_yaml(const std::string& text) {
    ReferenceView view;
    if (text.find_first_not_of(" \t\r\n") == std::string::npos)
        throw geometry::FileFormatError("empty: not an OpenCV YAML file");
    try {
        geometry::check_yaml_text(text);
        cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
        if (!fs.isOpened()) throw geometry::FileFormatError("not an OpenCV YAML file");
        if (fs["dictionary"].empty() || !fs["dictionary"].isString())
            throw geometry::FileFormatError("missing key 'dictionary'");
        fs["dictionary"] >> view.dictionary;
        const cv::FileNode marks = fs["marks"];
        if (!marks.isSeq())
            throw geometry::FileFormatError("missing or malformed 'marks' (a list)");
        for (const auto& node : marks) {
            DetectedMarker m;
            if (!node["id"].isInt()) throw geometry::FileFormatError("a mark without an 'id'");
            node["id"] >> m.id;
            const cv::FileNode corners = node["corners"];
            if (!corners.isSeq() || corners.size() != 8)
                throw geometry::FileFormatError("mark " + std::to_string(m.id) +
                                                ": 'corners' must be 8 numbers");
            for (std::size_t k = 0; k < 4; ++k) {
                m.corners[k] = {static_cast<double>(corners[static_cast<int>(2 * k)]),
                                static_cast<double>(corners[static_cast<int>(2 * k + 1)])};
                if (!std::isfinite(m.corners[k].x) || !std::isfinite(m.corners[k].y))
                    throw geometry::FileFormatError("mark " + std::to_string(m.id) +
                                                    ": corners must be finite");
            }
            view.marks.push_back(m);
        }
    } catch (...) {
        geometry::rethrow_as_file_format_error();
    }
    return view;
}

CameraMove compare_reference(const ReferenceView& stored, const ReferenceView& now,
                             const geometry::CameraModel& camera, const geometry::BedPlane& plane) {
    std::map<int, const DetectedMarker*> found;
    for (const auto& m : now.marks) found.emplace(m.id, &m);
    std::vector<geometry::Point2> before, after;
    CameraMove move;
    for (const auto& m : stored.marks) {
        const auto it = found.find(m.id);
        if (it == found.end()) {
            move.missing.push_back(m.id);
            continue;
        }
        ++move.marks_compared;
        before.insert(before.end(), m.corners.begin(), m.corners.end());
        after.insert(after.end(), it->second->corners.begin(), it->second->corners.end());
    }
    if (before.empty()) return move;
    const auto a = geometry::pixels_to_bed(camera, plane, before, 0);
    const auto b = geometry::pixels_to_bed(camera, plane, after, 0);
    double sum_sq = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        const double d = std::hypot(b[k].x - a[k].x, b[k].y - a[k].y);
        move.largest_mm = std::max(move.largest_mm, d);
        sum_sq += d * d;
    }
    move.rms_mm = std::sqrt(sum_sq / static_cast<double>(a.size()));
    return move;
}

}  // namespace calbox::vision
