// The cycle's set-up stages (firmware/cycle/cycle.hpp): the camera calibrated from views of a board
// held in front of it, the bed plane from a board laid on the bed (with the fixed reference
// marks' view beside it), and each cycle's check of the camera against those marks. A box does
// them once, and again when its camera moves.
#include <cmath>

#include "core/geometry/calibration.hpp"
#include "core/number_text.hpp"
#include "core/vision/reference_marks.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/cycle/photos.hpp"

namespace calbox::firmware {
namespace {

// The fixed reference marks in the plane's photo, as their YAML, their count added to `summary`.
// The marks' view is taken with the plane, in the same photo: the two hold together until the
// camera moves. Throws geometry::CalibrationError with fewer in view than the check needs.
std::string reference_marks_yaml(const vision::GrayView& photo, const std::string& marks,
                                 const geometry::CameraModel& camera, std::string& summary) {
    const auto reference = vision::find_reference_marks(photo, marks, camera);
    if (static_cast<int>(reference.marks.size()) < kMinimumReferenceMarks)
        throw geometry::CalibrationError(
            std::to_string(reference.marks.size()) + " of the at least " +
            std::to_string(kMinimumReferenceMarks) + " fixed reference marks (" + marks +
            ") in view: stick them on the frame or the bed outside the work area and clear of "
            "the board, or set setup.reference_marks = none to run without the camera check");
    summary += ", " + std::to_string(reference.marks.size()) + " reference marks";
    return vision::reference_to_yaml(reference);
}

}  // namespace

std::string Cycle::calibrate_camera() {
    if (state_ != CycleState::idle) return std::string("busy: ") + state_name(state_);
    take_next_settings();
    error_.clear();
    setup_only_ = true;
    calibration_views_.clear();
    setup_coverage_ = 0;
    enter(CycleState::setup_camera, "set-up: calibrating the camera from " +
                                        std::to_string(settings_.calibration_views) + " views of " +
                                        settings_.calibration_pattern);
    setup_camera_view(0);
    return {};
}

std::string Cycle::take_plane() {
    if (state_ != CycleState::idle) return std::string("busy: ") + state_name(state_);
    if (!d_.data.read_file("camera.yaml"))
        return "the camera is not calibrated yet: camera calibrate first";
    take_next_settings();
    error_.clear();
    setup_only_ = true;
    enter(CycleState::setup_plane, "set-up: the bed plane");
    setup_plane();
    return {};
}

void Cycle::setup_camera_view(int view) {
    ask(Prompt::hold_calibration_board, view, [this, view] {
        capture(1, [this, view](std::vector<hal::Frame> frames) {
            // Each view's board is found as it is taken, so that the person knows at once
            // whether it counted and how much of the image the views cover so far.
            auto frame = std::make_shared<hal::Frame>(std::move(frames.front()));
            auto found = std::make_shared<std::optional<geometry::BoardObservation>>();
            work(
                [frame, found, pattern = settings_.calibration_pattern] {
                    *found = geometry::find_board(geometry::parse_pattern_spec(pattern),
                                                  view_of(*frame));
                },
                [this, view, frame, found] { take_calibration_view(view, *frame, *found); });
        });
    });
}

void Cycle::take_calibration_view(int view, const hal::Frame& frame,
                                  const std::optional<geometry::BoardObservation>& found) {
    const std::string of =
        std::to_string(view + 1) + "/" + std::to_string(settings_.calibration_views);
    if (!found) {
        notice("view " + of + ": no board found; hold it fully in view and press again");
        setup_camera_view(view);
        return;
    }
    image_size_ = {frame.width_px, frame.height_px};
    calibration_views_.push_back({"view " + std::to_string(view + 1), *found});
    setup_coverage_ = geometry::image_coverage(calibration_views_, frame.width_px, frame.height_px);
    notice("view " + of + ": " + std::to_string(found->image_points.size()) + " corners, " +
           std::to_string(static_cast<int>(std::lround(100 * setup_coverage_))) +
           " % of the image covered");
    if (view + 1 < settings_.calibration_views) {
        setup_camera_view(view + 1);
        return;
    }
    auto yaml = std::make_shared<std::string>();
    auto summary = std::make_shared<std::string>();
    auto views =
        std::make_shared<std::vector<geometry::ObservedView>>(std::move(calibration_views_));
    calibration_views_.clear();
    work(
        [views, yaml, summary, size = image_size_] {
            const auto result = geometry::calibrate_from_views(geometry::LensModel::pinhole, *views,
                                                               size[0], size[1]);
            std::vector<double> per_view;
            for (const auto& v : result.views) per_view.push_back(v.rms_px);
            *yaml = geometry::camera_to_yaml(result.camera, per_view);
            *summary = "camera calibrated from " + std::to_string(result.views.size()) +
                       " views, RMS " + number_text("%.3f", result.camera.rms_px) + " px";
            for (const auto& d : result.dropped) *summary += "; dropped " + d.name + ": " + d.why;
        },
        [this, yaml, summary] {
            if (!keep("camera.yaml", *yaml)) return;
            // A new camera model makes the old plane's pose stale: the plane is taken again.
            try {
                d_.data.remove_file("plane.yaml");
            } catch (const std::runtime_error& e) {
                fail(std::string("records: ") + e.what());
                return;
            }
            notice(*summary);
            enter(CycleState::setup_plane, "set-up: the bed plane");
            setup_plane();
        });
}

void Cycle::setup_plane() {
    ask(Prompt::lay_plane_board, 0, [this] {
        capture(1, [this](std::vector<hal::Frame> frames) {
            auto frame = std::make_shared<hal::Frame>(std::move(frames.front()));
            auto yaml = std::make_shared<std::string>();
            auto reference_yaml = std::make_shared<std::string>();
            auto summary = std::make_shared<std::string>();
            const std::string camera_yaml = d_.data.read_file("camera.yaml").value_or("");
            work(
                [frame, yaml, reference_yaml, summary, camera_yaml,
                 pattern = settings_.plane_pattern, thickness = settings_.plane_board_thickness_mm,
                 marks = settings_.reference_marks] {
                    const auto camera = geometry::camera_from_yaml(camera_yaml);
                    const auto plane = geometry::estimate_bed_plane(
                        camera, geometry::parse_pattern_spec(pattern), view_of(*frame), thickness);
                    *yaml = geometry::plane_to_yaml(plane);
                    *summary = "bed plane from " + pattern + ", RMS " +
                               number_text("%.3f", plane.rms_px) + " px" +
                               geometry::set_aside_text(plane);
                    if (marks == kNoReferenceMarks) return;
                    *reference_yaml =
                        reference_marks_yaml(view_of(*frame), marks, camera, *summary);
                },
                [this, yaml, reference_yaml, summary] {
                    keep_plane(*yaml, *reference_yaml, *summary);
                });
        });
    });
}

void Cycle::keep_plane(const std::string& yaml, const std::string& reference_yaml,
                       const std::string& summary) {
    // The plane last: a plane on file always has its marks' view beside it.
    try {
        if (reference_yaml.empty()) d_.data.remove_file(kReferenceFile);
    } catch (const std::runtime_error& e) {
        fail(std::string("records: ") + e.what());
        return;
    }
    if (!reference_yaml.empty() && !keep(kReferenceFile, reference_yaml)) return;
    if (!keep("plane.yaml", yaml)) return;
    notice(summary);
    if (setup_only_) {
        setup_only_ = false;
        enter(CycleState::idle, "set-up done: " + summary);
        return;
    }
    ask_clear_bed_then_target();
}

void Cycle::check_camera() {
    if (settings_.reference_marks == kNoReferenceMarks) {
        ask_clear_bed_then_target();
        return;
    }
    const auto stored = d_.data.read_file(kReferenceFile);
    if (!stored) {
        enter(CycleState::setup_plane, "set-up: checking the camera");
        fail("the camera check: no stored view of the reference marks (" +
                 std::string(kReferenceFile) +
                 "); take the plane again (console: camera plane) with the marks in view",
             "take the plane again");
        return;
    }
    enter(CycleState::setup_plane, "set-up: checking the camera against the reference marks");
    capture(1, [this, stored = *stored](std::vector<hal::Frame> frames) {
        auto frame = std::make_shared<hal::Frame>(std::move(frames.front()));
        auto move = std::make_shared<vision::CameraMove>();
        work(
            [frame, move, stored, camera_yaml = d_.data.read_file("camera.yaml").value_or(""),
             plane_yaml = d_.data.read_file("plane.yaml").value_or("")] {
                const auto reference = vision::reference_from_yaml(stored);
                const auto camera = geometry::camera_from_yaml(camera_yaml);
                *move = vision::compare_reference(
                    reference,
                    vision::find_reference_marks_again(calibrated_view_of(*frame, camera),
                                                       reference, camera),
                    camera, geometry::plane_from_yaml(plane_yaml));
            },
            [this, move] {
                const std::string seen =
                    std::to_string(move->marks_compared) + " of " +
                    std::to_string(move->marks_compared + static_cast<int>(move->missing.size())) +
                    " reference marks";
                if (move->marks_compared < kMinimumReferenceMarks || !move->missing.empty()) {
                    std::string ids;
                    for (int id : move->missing)
                        ids += (ids.empty() ? "" : ", ") + std::to_string(id);
                    fail("the camera check: " + seen + " found (missing: " + ids +
                             "); the camera has moved or a mark is covered: uncover the marks or "
                             "take the plane again (console: camera plane)",
                         "marks hidden or moved");
                    return;
                }
                report_.camera_move_mm = move->largest_mm;
                const std::string moved =
                    "largest apparent move " + number_text("%.3f", move->largest_mm) +
                    " mm (limit " + number_text("%.3f", settings_.camera_moved_limit_mm) + " mm)";
                if (move->largest_mm > settings_.camera_moved_limit_mm) {
                    fail("the camera has moved since the plane was taken: " + seen + ", " + moved +
                             "; fix the camera's mount, then take the plane again (console: "
                             "camera plane)",
                         "camera moved: replane");
                    return;
                }
                notice("camera check: " + seen + ", " + moved);
                ask_clear_bed_then_target();
            });
    });
}

}  // namespace calbox::firmware
