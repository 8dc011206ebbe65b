#include "core/geometry/camera_model.hpp"

#include <cctype>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/persistence.hpp>
#include <string_view>

#include "core/geometry/cv_convert.hpp"

namespace calbox::geometry {

std::vector<Point2> undistort_to_normalized(const CameraModel& camera,
                                            const std::vector<Point2>& pixels) {
    if (pixels.empty()) return {};
    const auto in = to_cv(pixels);
    std::vector<cv::Point2d> out;
    const cv::Mat k = camera_matrix_of(camera);
    if (camera.model == LensModel::fisheye) {
        cv::fisheye::undistortPoints(in, out, k, camera.distortion);
    } else {
        // Iterate well past OpenCV's default 5 steps: strong lenses need it for 1e-4 px.
        cv::undistortPoints(
            in, out, k, camera.distortion, cv::noArray(), cv::noArray(),
            cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
    }
    return from_cv(out);
}

std::vector<Point2> distort_from_normalized(const CameraModel& camera,
                                            const std::vector<Point2>& normalized) {
    std::vector<Point3> rays;
    rays.reserve(normalized.size());
    for (const auto& n : normalized) rays.push_back({n.x, n.y, 1.0});
    return project_points(camera, RigidPose{}, rays);
}

std::vector<Point2> project_points(const CameraModel& camera, const RigidPose& pose,
                                   const std::vector<Point3>& points) {
    if (points.empty()) return {};
    std::vector<cv::Point3d> in;
    in.reserve(points.size());
    for (const auto& p : points) in.emplace_back(p.x, p.y, p.z);
    const cv::Vec3d rvec(pose.rvec[0], pose.rvec[1], pose.rvec[2]);
    const cv::Vec3d tvec(pose.tvec_mm[0], pose.tvec_mm[1], pose.tvec_mm[2]);
    std::vector<cv::Point2d> out;
    if (camera.model == LensModel::fisheye) {
        cv::fisheye::projectPoints(in, out, rvec, tvec, camera_matrix_of(camera),
                                   camera.distortion);
    } else {
        cv::projectPoints(in, rvec, tvec, camera_matrix_of(camera), camera.distortion, out);
    }
    return from_cv(out);
}

std::string camera_to_yaml(const CameraModel& camera, const std::vector<double>& per_view_rms_px) {
    cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    fs << "model" << (camera.model == LensModel::fisheye ? "fisheye" : "pinhole");
    fs << "image_width" << camera.image_width;
    fs << "image_height" << camera.image_height;
    fs << "camera_matrix" << camera_matrix_of(camera);
    fs << "distortion_coefficients" << cv::Mat(camera.distortion, true).reshape(1, 1);
    fs << "rms" << camera.rms_px;
    if (!per_view_rms_px.empty()) fs << "per_view_rms" << per_view_rms_px;
    return fs.releaseAndGetString();
}

void rethrow_as_file_format_error() {
    try {
        throw;
    } catch (const FileFormatError&) {
        throw;
    } catch (const cv::Exception& e) {
        throw FileFormatError(std::string("corrupt YAML: ") + e.err);
    } catch (const std::exception& e) {
        throw FileFormatError(std::string("corrupt YAML: ") + e.what());
    }
}

void check_yaml_text(const std::string& text) {
    // OpenCV writes every file the box keeps with this header; without it a mangled first line
    // hides where the document starts.
    if (text.rfind("%YAML:1.0\n---", 0) != 0 && text.rfind("%YAML:1.0\r\n---", 0) != 0)
        throw FileFormatError("corrupt YAML: it does not start with '%YAML:1.0' and '---'");
    std::string open;  // the brackets still open, innermost last
    int line = 1;
    char quote = 0;
    char before = '\n';  // the last character that was not a space
    bool comment = false;
    int documents = 0;
    bool seen_first_key = false;
    for (std::size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (c == '\n') {
            ++line;
            comment = false;
            before = '\n';
            continue;
        }
        if (before == '\n' && quote == 0 && text.compare(i, 3, "---") == 0 && ++documents > 1) {
            throw FileFormatError("corrupt YAML: line " + std::to_string(line) +
                                  ": a second document; the file holds one");
        }
        // The document's first line is a key at the margin, as every file the box writes has
        // it: an indented one sends OpenCV's parser round for ever.
        if (documents == 1 && !seen_first_key && before == '\n' && c != '-' && c != '\r' &&
            c != '#') {
            if (!(std::isalpha(static_cast<unsigned char>(c)) || c == '_')) {
                throw FileFormatError("corrupt YAML: line " + std::to_string(line) +
                                      ": the document does not start with a key");
            }
            seen_first_key = true;
        }
        if (comment) continue;
        if (quote != 0) {
            if (c == quote) quote = 0;
            continue;
        }
        const char previous = before;
        if (c != ' ' && c != '\t') before = c;
        // A quote opens a quoted scalar only where a value starts; inside a plain one it is text.
        const bool value_starts = std::string_view("\n:,[{-").find(previous) != std::string::npos;
        if ((c == '"' || c == '\'') && value_starts) {
            quote = c;
        } else if (c == '#') {
            comment = true;
        } else if (c == '[' || c == '{') {
            open.push_back(c);
        } else if (c == ']' || c == '}') {
            if (open.empty() || open.back() != (c == ']' ? '[' : '{')) {
                throw FileFormatError("corrupt YAML: line " + std::to_string(line) + ": '" +
                                      std::string(1, c) + "' closes nothing open");
            }
            open.pop_back();
        }
    }
    if (!open.empty()) {
        throw FileFormatError("corrupt YAML: a '" + std::string(1, open.back()) +
                              "' is never closed");
    }
}

CameraModel camera_from_yaml(const std::string& text) {
    CameraModel c;
    try {
        check_yaml_text(text);
        cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
        if (!fs.isOpened()) throw FileFormatError("not an OpenCV YAML file");
        const auto node = [&](const char* key) {
            cv::FileNode n = fs[key];
            if (n.empty()) throw FileFormatError(std::string("missing key '") + key + "'");
            return n;
        };
        std::string model;
        node("model") >> model;
        if (model == "pinhole") {
            c.model = LensModel::pinhole;
        } else if (model == "fisheye") {
            c.model = LensModel::fisheye;
        } else {
            throw FileFormatError("model must be pinhole or fisheye, not '" + model + "'");
        }
        node("image_width") >> c.image_width;
        node("image_height") >> c.image_height;
        if (c.image_width <= 0 || c.image_height <= 0)
            throw FileFormatError("image size must be positive");
        cv::Mat k, d;
        node("camera_matrix") >> k;
        node("distortion_coefficients") >> d;
        if (k.rows != 3 || k.cols != 3) throw FileFormatError("camera_matrix must be 3x3");
        k.convertTo(k, CV_64F);
        for (int i = 0; i < 9; ++i)
            c.camera_matrix[static_cast<std::size_t>(i)] = k.at<double>(i / 3, i % 3);
        if (!(c.fx() > 0 && c.fy() > 0))
            throw FileFormatError("camera_matrix needs positive focal lengths");
        d.convertTo(d, CV_64F);
        c.distortion.assign(d.begin<double>(), d.end<double>());
        const std::size_t expected = c.model == LensModel::fisheye ? 4 : 5;
        if (c.distortion.size() != expected &&
            !(c.model == LensModel::pinhole &&
              (c.distortion.size() == 4 || c.distortion.size() == 8))) {
            throw FileFormatError("distortion_coefficients needs " + std::to_string(expected) +
                                  " values for a " + model + " camera");
        }
        for (double v : c.distortion)
            if (!std::isfinite(v)) throw FileFormatError("distortion_coefficients must be finite");
        if (!fs["rms"].empty()) fs["rms"] >> c.rms_px;
    } catch (...) {
        rethrow_as_file_format_error();
    }
    return c;
}

}  // namespace calbox::geometry
