#include "core/geometry/camera_model.hpp"

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/persistence.hpp>

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

CameraModel camera_from_yaml(const std::string& text) {
    CameraModel c;
    try {
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
    } catch (const cv::Exception& e) {
        throw FileFormatError(std::string("corrupt YAML: ") + e.err);
    }
    return c;
}

}  // namespace calbox::geometry
