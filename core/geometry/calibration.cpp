#include "core/geometry/calibration.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/persistence.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/geometry/cv_convert.hpp"

namespace calbox::geometry {
namespace {

std::vector<cv::Point3f> object_points_f(const std::vector<Point3>& points) {
    std::vector<cv::Point3f> out;
    out.reserve(points.size());
    for (const auto& p : points)
        out.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z));
    return out;
}

std::vector<cv::Point2f> image_points_f(const std::vector<Point2>& points) {
    std::vector<cv::Point2f> out;
    out.reserve(points.size());
    for (const auto& p : points) out.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
    return out;
}

double rms_between(const std::vector<Point2>& a, const std::vector<Point2>& b) {
    double sum = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
        sum += std::pow(a[i].x - b[i].x, 2) + std::pow(a[i].y - b[i].y, 2);
    return a.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(a.size()));
}

cv::Matx33d rotation_of(const RigidPose& p) {
    cv::Matx33d r;
    cv::Rodrigues(cv::Vec3d(p.rvec[0], p.rvec[1], p.rvec[2]), r);
    return r;
}

}  // namespace

namespace {

void check_minimum(LensModel model, const std::vector<ObservedView>& views,
                   const std::string& found_in) {
    const CalibrationMinimum need = calibration_minimum(model);
    std::size_t corners = 0;
    for (const auto& v : views) corners += v.board.image_points.size();
    if (static_cast<int>(views.size()) >= need.views &&
        corners >= static_cast<std::size_t>(need.corners))
        return;
    throw CalibrationError("the board was found in " + found_in + " (" + std::to_string(corners) +
                           " corners); a " + lens_model_name(model) +
                           " calibration needs at least " + std::to_string(need.views) +
                           " views and " + std::to_string(need.corners) + " corners");
}

}  // namespace

CalibrationMinimum calibration_minimum(LensModel model) {
    return model == LensModel::fisheye ? CalibrationMinimum{4, 80} : CalibrationMinimum{3, 60};
}

CalibrationResult calibrate_camera(const PatternSpec& pattern, LensModel model,
                                   const std::vector<NamedImage>& images) {
    std::vector<ObservedView> found;
    std::vector<std::string> skipped;
    cv::Size size;
    for (const auto& image : images) {
        const cv::Size this_size(image.image.width_px, image.image.height_px);
        if (size.area() == 0) size = this_size;
        if (this_size != size) {
            throw CalibrationError("image " + image.name + " is " +
                                   std::to_string(this_size.width) + "x" +
                                   std::to_string(this_size.height) + ", the others " +
                                   std::to_string(size.width) + "x" + std::to_string(size.height));
        }
        auto obs = find_board(pattern, image.image);
        if (!obs) {
            skipped.push_back(image.name);
            continue;
        }
        found.push_back({image.name, std::move(*obs)});
    }
    check_minimum(
        model, found,
        std::to_string(found.size()) + " of " + std::to_string(images.size()) + " images");
    auto result = calibrate_from_views(model, found, size.width, size.height);
    result.skipped = std::move(skipped);
    return result;
}

double image_coverage(const std::vector<ObservedView>& views, int width_px, int height_px) {
    constexpr int kColumns = 8, kRows = 6;
    if (width_px <= 0 || height_px <= 0) return 0;
    std::array<bool, std::size_t{kColumns} * kRows> covered{};
    for (const auto& v : views) {
        for (const auto& p : v.board.image_points) {
            const int c = static_cast<int>(p.x * kColumns / width_px);
            const int r = static_cast<int>(p.y * kRows / height_px);
            if (c >= 0 && c < kColumns && r >= 0 && r < kRows)
                covered[static_cast<std::size_t>(r) * kColumns + static_cast<std::size_t>(c)] =
                    true;
        }
    }
    return static_cast<double>(std::count(covered.begin(), covered.end(), true)) /
           (kColumns * kRows);
}

namespace {

struct IntrinsicSolve {
    CameraModel camera;
    std::vector<double> view_rms_px;
};

// OpenCV's solve over `boards`; from `guess` when given (its views' poses are then started from
// the guess's intrinsics, which is what brings round a view whose own start did not converge).
IntrinsicSolve solve_intrinsics(LensModel model, const std::vector<const BoardObservation*>& boards,
                                cv::Size size, const CameraModel* guess) {
    std::vector<std::vector<cv::Point3f>> object;
    std::vector<std::vector<cv::Point2f>> image;
    for (const auto* o : boards) {
        object.push_back(object_points_f(o->object_points));
        image.push_back(image_points_f(o->image_points));
    }
    cv::Mat k, d;
    std::vector<cv::Mat> rvecs, tvecs;
    IntrinsicSolve out;
    CameraModel& camera = out.camera;
    camera.model = model;
    camera.image_width = size.width;
    camera.image_height = size.height;
    const cv::TermCriteria until(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 200, 1e-12);
    try {
        if (model == LensModel::fisheye) {
            std::vector<std::vector<cv::Point3d>> object_d;
            std::vector<std::vector<cv::Point2d>> image_d;
            for (std::size_t v = 0; v < object.size(); ++v) {
                object_d.emplace_back(object[v].begin(), object[v].end());
                image_d.emplace_back(image[v].begin(), image[v].end());
            }
            cv::Matx33d kk;
            cv::Vec4d dd;
            int flags = cv::fisheye::CALIB_RECOMPUTE_EXTRINSIC | cv::fisheye::CALIB_FIX_SKEW;
            if (guess) {
                kk = cv::Matx33d(guess->camera_matrix.data());
                for (int i = 0; i < 4; ++i)
                    dd[i] = guess->distortion.at(static_cast<std::size_t>(i));
                flags |= cv::fisheye::CALIB_USE_INTRINSIC_GUESS;
            }
            cv::fisheye::calibrate(object_d, image_d, size, kk, dd, rvecs, tvecs, flags, until);
            k = cv::Mat(kk);
            d = cv::Mat(dd);
        } else {
            int flags = 0;
            if (guess) {
                k = cv::Mat(cv::Matx33d(guess->camera_matrix.data()));
                d = cv::Mat(guess->distortion, true);
                flags |= cv::CALIB_USE_INTRINSIC_GUESS;
            }
            cv::calibrateCamera(object, image, size, k, d, rvecs, tvecs, flags, until);
        }
    } catch (const cv::Exception& e) {
        throw CalibrationError(std::string("OpenCV could not calibrate from these views: ") +
                               e.err);
    }
    k.convertTo(k, CV_64F);
    for (int i = 0; i < 9; ++i)
        camera.camera_matrix[static_cast<std::size_t>(i)] = k.at<double>(i / 3, i % 3);
    d.convertTo(d, CV_64F);
    camera.distortion.assign(d.begin<double>(), d.end<double>());
    double sum = 0;
    std::size_t count = 0;
    for (std::size_t v = 0; v < boards.size(); ++v) {
        RigidPose pose;
        for (int i = 0; i < 3; ++i) {
            pose.rvec[static_cast<std::size_t>(i)] = rvecs[v].at<double>(i);
            pose.tvec_mm[static_cast<std::size_t>(i)] = tvecs[v].at<double>(i);
        }
        const auto projected = project_points(camera, pose, boards[v]->object_points);
        const double rms = rms_between(projected, boards[v]->image_points);
        out.view_rms_px.push_back(rms);
        sum += rms * rms * static_cast<double>(projected.size());
        count += projected.size();
    }
    camera.rms_px = std::sqrt(sum / static_cast<double>(count));
    return out;
}

// The level the better views reach: their lower quartile, which stays with the good views even
// when half of a small set is off (a median would then sit between the two groups).
double typical_rms_px(std::vector<double> values) {
    std::sort(values.begin(), values.end());
    return values[(values.size() - 1) / 4];
}

std::string px_text(double px) {
    char text[32];
    std::snprintf(text, sizeof text, "%.2f px", px);
    return text;
}

}  // namespace

RigidPose solve_board_pose(const CameraModel& camera, const BoardObservation& board) {
    // Pose from undistorted points with an ideal camera: the same path for both lens models.
    const auto normalized = undistort_to_normalized(camera, board.image_points);
    std::vector<cv::Point3d> object;
    for (const auto& p : board.object_points) object.emplace_back(p.x, p.y, p.z);
    cv::Vec3d rvec, tvec;
    try {
        if (!cv::solvePnP(object, to_cv(normalized), cv::Matx33d::eye(), cv::noArray(), rvec, tvec,
                          false, cv::SOLVEPNP_IPPE))
            throw CalibrationError("the board's pose could not be solved (solvePnP failed)");
        cv::solvePnPRefineLM(object, to_cv(normalized), cv::Matx33d::eye(), cv::noArray(), rvec,
                             tvec);
    } catch (const cv::Exception& e) {
        throw CalibrationError(std::string("the board's pose could not be solved: ") + e.err);
    }
    if (!(tvec[2] > 0)) throw CalibrationError("the board's solved pose puts it behind the camera");
    RigidPose pose;
    for (int i = 0; i < 3; ++i) {
        pose.rvec[static_cast<std::size_t>(i)] = rvec[i];
        pose.tvec_mm[static_cast<std::size_t>(i)] = tvec[i];
    }
    return pose;
}

double calibration_max_rms_px(LensModel model) {
    return model == LensModel::fisheye ? 1.5 : 1.0;
}

namespace {

// A view's pose solved through another solve's camera: its reprojection, infinite where no pose
// converges.
double reprojected_through(const CameraModel& camera, const BoardObservation& board) {
    try {
        const RigidPose pose = solve_board_pose(camera, board);
        return rms_between(project_points(camera, pose, board.object_points), board.image_points);
    } catch (const CalibrationError&) {
        return std::numeric_limits<double>::infinity();
    }
}

// Why a view far off the others is dropped: its reprojection in the first solve against the
// typical view's, and through the other views' camera.
std::string far_off(double view_px, double typical_px, double resolved_px) {
    return "reprojects at " + px_text(view_px) + " against the better views' " +
           px_text(typical_px) + ", and " +
           (std::isfinite(resolved_px) ? px_text(resolved_px) : std::string("no pose")) +
           " through their camera: its corners do not fit the lens the others show "
           "(mis-ordered, another board, or past the lens model's reach)";
}

// The views the final solve used, each with its reprojection and note, and its camera; refused
// past the lens model's limit.
void list_views_used(LensModel model, const std::vector<ObservedView>& views,
                     const std::vector<std::size_t>& used, const IntrinsicSolve& solve,
                     const std::vector<std::string>& notes, CalibrationResult& result) {
    for (std::size_t i = 0; i < used.size(); ++i) {
        const auto& view = views[used[i]];
        result.views.push_back({view.name, static_cast<int>(view.board.image_points.size()),
                                solve.view_rms_px[i], view.board.detector, notes[used[i]]});
    }
    result.camera = solve.camera;
    const double max_rms_px = calibration_max_rms_px(model);
    if (!(result.camera.rms_px <= max_rms_px))
        throw CalibrationError("the " + std::string(lens_model_name(model)) +
                               " calibration reprojects at " + px_text(result.camera.rms_px) +
                               " RMS over " + std::to_string(result.views.size()) +
                               " views (at most " + px_text(max_rms_px) +
                               "): is the lens model right, and the board flat and sharp?");
}

}  // namespace

CalibrationResult calibrate_from_views(LensModel model, const std::vector<ObservedView>& views,
                                       int width_px, int height_px, const ViewJudging& judging) {
    check_minimum(model, views, std::to_string(views.size()) + " views");
    const cv::Size size(width_px, height_px);
    const auto boards_of = [&](const std::vector<std::size_t>& which) {
        std::vector<const BoardObservation*> boards;
        boards.reserve(which.size());
        for (const auto v : which) boards.push_back(&views[v].board);
        return boards;
    };
    // How far a view may reproject, against the better views of a solve.
    const auto limit_px_of = [&](const IntrinsicSolve& s) {
        return std::max(judging.outlier_factor * typical_rms_px(s.view_rms_px),
                        judging.outlier_floor_px);
    };
    std::vector<std::size_t> every(views.size());
    for (std::size_t v = 0; v < views.size(); ++v) every[v] = v;
    IntrinsicSolve solve = solve_intrinsics(model, boards_of(every), size, nullptr);

    // A view whose reprojection stands far above the others' was solved wrong (its pose did not
    // converge from OpenCV's start) or found wrong (corners mis-ordered, another board): it pulls
    // every intrinsic towards it. It is set aside, the rest solved, and then its pose solved
    // through the rest's camera: a view that then fits rejoins, one that does not is dropped.
    const double first_typical = typical_rms_px(solve.view_rms_px);
    const double limit_px = limit_px_of(solve);
    std::vector<std::size_t> kept, outliers;
    for (std::size_t v = 0; v < views.size(); ++v)
        (solve.view_rms_px[v] > limit_px ? outliers : kept).push_back(v);

    CalibrationResult result;
    std::vector<std::size_t> used = kept;
    std::vector<std::string> notes(views.size());
    if (!outliers.empty()) {
        std::vector<ObservedView> rest;
        rest.reserve(kept.size());
        for (const auto v : kept) rest.push_back(views[v]);
        std::string dropped_names;
        for (const auto v : outliers)
            dropped_names += (dropped_names.empty() ? "" : ", ") + views[v].name;
        check_minimum(model, rest,
                      std::to_string(rest.size()) + " views once " + dropped_names +
                          " (far off the others) were set aside");
        IntrinsicSolve without = solve_intrinsics(model, boards_of(kept), size, nullptr);
        const double rest_limit_px = limit_px_of(without);
        std::vector<std::size_t> rejoined;
        for (const auto v : outliers) {
            const double resolved_px = reprojected_through(without.camera, views[v].board);
            if (resolved_px <= rest_limit_px) {
                rejoined.push_back(v);
                notes[v] = "re-solved: its pose had not converged (" +
                           px_text(solve.view_rms_px[v]) + "), through the other views' camera " +
                           px_text(resolved_px);
            } else {
                result.dropped.push_back(
                    {views[v].name, far_off(solve.view_rms_px[v], first_typical, resolved_px)});
            }
        }
        solve = std::move(without);
        if (!rejoined.empty()) {
            std::vector<std::size_t> all = kept;
            all.insert(all.end(), rejoined.begin(), rejoined.end());
            IntrinsicSolve with = solve_intrinsics(model, boards_of(all), size, &solve.camera);
            bool all_fit = true;
            for (const double rms : with.view_rms_px) all_fit = all_fit && rms <= rest_limit_px;
            if (all_fit) {
                solve = std::move(with);
                used = std::move(all);
            } else {
                for (const auto v : rejoined)
                    result.dropped.push_back({views[v].name,
                                              "fits alone through the other views' camera but not "
                                              "solved with them: left out"});
            }
        }
    }
    list_views_used(model, views, used, solve, notes, result);
    return result;
}

BedPlane estimate_bed_plane(const CameraModel& camera, const PatternSpec& pattern,
                            const vision::GrayView& image, double board_thickness_mm,
                            double max_rms_px) {
    if (!(board_thickness_mm >= 0 && board_thickness_mm < 100)) {
        throw CalibrationError("board thickness must be 0..100 mm");
    }
    if (const auto size = photo_size_mismatch(camera, image.width_px, image.height_px);
        !size.empty())
        throw CalibrationError("the image is " + size);
    const ChessboardSearch search;
    const auto obs = find_board(pattern, image, search);
    if (!obs) {
        throw CalibrationError(board_not_found(pattern, image, search));
    }
    const std::size_t found = obs->ids.size() + obs->set_aside_ids.size();
    if (2 * obs->ids.size() < found)
        throw CalibrationError(
            "the board was found under glare: " + std::to_string(obs->set_aside_ids.size()) +
            " of its " + std::to_string(found) +
            " corners are washed out; tilt the board or diffuse the lamp's light");
    const RigidPose board = solve_board_pose(camera, *obs);
    BedPlane plane;
    plane.board_thickness_mm = board_thickness_mm;
    plane.set_aside_corners = obs->set_aside_ids;
    plane.corners_used = static_cast<int>(obs->ids.size());
    plane.rms_px =
        rms_between(project_points(camera, board, obs->object_points), obs->image_points);
    if (!(plane.rms_px <= max_rms_px)) {
        char why[200];
        std::snprintf(why, sizeof why,
                      "the plane's board reprojects to %.2f px RMS (at most %.2f px): is the board "
                      "flat and wholly on the bed, and camera.yaml this camera's calibration?",
                      plane.rms_px, max_rms_px);
        throw CalibrationError(why);
    }
    // Turn the board frame over about its x axis (z up, still right-handed), then drop the origin
    // from the board's surface to the bed's: the bed origin is the board point (0, 0, thickness).
    const cv::Matx33d r_board = rotation_of(board);
    const cv::Matx33d r_bed = r_board * cv::Matx33d(1, 0, 0, 0, -1, 0, 0, 0, -1);
    const cv::Vec3d t_bed = cv::Vec3d(board.tvec_mm[0], board.tvec_mm[1], board.tvec_mm[2]) +
                            r_board * cv::Vec3d(0, 0, board_thickness_mm);
    cv::Vec3d r;
    cv::Rodrigues(r_bed, r);
    for (int i = 0; i < 3; ++i) {
        plane.bed_to_camera.rvec[static_cast<std::size_t>(i)] = r[i];
        plane.bed_to_camera.tvec_mm[static_cast<std::size_t>(i)] = t_bed[i];
    }
    return plane;
}

std::string set_aside_text(const BedPlane& plane) {
    if (plane.set_aside_corners.empty()) return "";
    std::string ids;
    for (const int id : plane.set_aside_corners)
        ids += (ids.empty() ? "" : ", ") + std::to_string(id);
    return ", " + std::to_string(plane.set_aside_corners.size()) + " of its " +
           std::to_string(plane.set_aside_corners.size() +
                          static_cast<std::size_t>(plane.corners_used)) +
           " corners set aside under glare (ids " + ids + ")";
}

std::string plane_to_yaml(const BedPlane& plane) {
    cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
    fs << "bed_rvec" << cv::Mat(3, 1, CV_64F, const_cast<double*>(plane.bed_to_camera.rvec.data()));
    fs << "bed_tvec"
       << cv::Mat(3, 1, CV_64F, const_cast<double*>(plane.bed_to_camera.tvec_mm.data()));
    fs << "board_thickness_mm" << plane.board_thickness_mm;
    fs << "rms" << plane.rms_px;
    return fs.releaseAndGetString();
}

BedPlane plane_from_yaml(const std::string& text) {
    BedPlane plane;
    try {
        check_yaml_text(text);
        cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
        if (!fs.isOpened()) throw FileFormatError("not an OpenCV YAML file");
        const auto vec3 = [&](const char* key, std::array<double, 3>& out) {
            cv::Mat m;
            fs[key] >> m;
            if (m.total() != 3)
                throw FileFormatError(std::string("missing or malformed '") + key +
                                      "' (3 numbers)");
            m.convertTo(m, CV_64F);
            for (int i = 0; i < 3; ++i) {
                out[static_cast<std::size_t>(i)] = m.at<double>(i);
                if (!std::isfinite(out[static_cast<std::size_t>(i)]))
                    throw FileFormatError(std::string(key) + " must be finite");
            }
        };
        vec3("bed_rvec", plane.bed_to_camera.rvec);
        vec3("bed_tvec", plane.bed_to_camera.tvec_mm);
        if (fs["board_thickness_mm"].empty())
            throw FileFormatError("missing key 'board_thickness_mm'");
        fs["board_thickness_mm"] >> plane.board_thickness_mm;
        if (!fs["rms"].empty()) fs["rms"] >> plane.rms_px;
    } catch (...) {
        rethrow_as_file_format_error();
    }
    return plane;
}

std::vector<Point3> pixels_to_bed(const CameraModel& camera, const BedPlane& plane,
                                  const std::vector<Point2>& pixels, double height_mm) {
    const auto normalized = undistort_to_normalized(camera, pixels);
    const cv::Matx33d r = rotation_of(plane.bed_to_camera);
    const cv::Matx33d rt = r.t();
    const cv::Vec3d t(plane.bed_to_camera.tvec_mm[0], plane.bed_to_camera.tvec_mm[1],
                      plane.bed_to_camera.tvec_mm[2]);
    const cv::Vec3d origin = -(rt * t);
    std::vector<Point3> out;
    out.reserve(pixels.size());
    for (const auto& n : normalized) {
        const cv::Vec3d d = rt * cv::Vec3d(n.x, n.y, 1.0);
        const double s = (height_mm - origin[2]) / d[2];
        if (!(s > 0) || !std::isfinite(s))
            throw CalibrationError("a pixel's ray does not meet the bed plane");
        out.push_back({origin[0] + s * d[0], origin[1] + s * d[1], height_mm});
    }
    return out;
}

}  // namespace calbox::geometry
