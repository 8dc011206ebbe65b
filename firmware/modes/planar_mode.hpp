#pragma once
// The planar mode's adapter (routers, cartesian machines): the machine's quasi-static error
// model, kept by the box (planar-result.json) and compensated into the jobs sent through it;
// verified on the grid drilled through it. The firmware's own scale and skew settings are shown
// beside it (firmware.txt), not sent: both would correct twice.
// A Klipper printer behind its host is the exception: the jobs it prints do not pass through the
// box, so its own settings carry the model's linear part (rotation_distance, a skew profile) and
// the box keeps no model for it (planar_klipper.cpp).
#include <memory>
#include <optional>

#include "core/models/klipper_config.hpp"
#include "core/modes/planar.hpp"
#include "core/modes/stock.hpp"
#include "core/vision/image_codec.hpp"
#include "core/image_view.hpp"
#include "firmware/modes/kept_correction.hpp"

namespace calbox::firmware {

constexpr const char* kPlanarResultFile = "planar-result.json";
constexpr const char* kNoPlanarResult = "none\n";

// A photo of the bed with the camera and plane it was taken through.
struct BedPhoto {
    vision::GrayPixels photo;
    geometry::CameraModel camera;
    geometry::BedPlane plane;
};

// A copy of `view`'s pixels, kept with the camera and plane.
BedPhoto bed_photo_of(const vision::GrayView& view, const geometry::CameraModel& camera,
                      const geometry::BedPlane& plane);

// The bed in the machine's coordinates as a picture for the eye (the records' bed-view.png and
// the console's `bed photo`): the machine's travel about 800 pixels across, the surface
// `surface_height_mm` above the bed; its PNG and world file, or nothing with why in `refused`.
// With `stock`, the sheet's outline is drawn on it too.
std::optional<std::pair<std::string, std::string>> bed_view_files(
    const BedPhoto& bed, const modes::PlanarSolution& solution, double surface_height_mm,
    std::string& refused, const modes::StockOutline* stock = nullptr);

class PlanarCycleMode final : public KeptCorrectionMode {
  public:
    PlanarCycleMode(models::MachineFile machine, CycleSteps& steps);
    const models::MachineFile& machine() const override { return machine_; }
    modes::ModeGoal goal() const override { return modes::planar_goal(); }
    void begin() override;
    void make_target(std::function<void(std::vector<std::string>)> then) override;
    void before_target(std::function<void()> then) override;
    void measure(MeasureInput input, std::function<void()> then) override;
    void solve(std::function<void(SolveOutcome)> then) override;
    ReviewText review() const override;
    void apply(std::function<void(bool verify)> then) override;
    std::string verify_detail() const override;
    void verification_job(const std::vector<std::string>& target,
                          std::function<void(std::vector<std::string>)> then) override;
    std::string revert(int number, std::function<void(std::string what)> then) override;
    void judge_verification(std::function<void(VerifyOutcome)> then) override;
    void describe_last(std::string&, nlohmann::json&) const override {}
    ModeResult result(bool) const override { return {}; }

    const std::optional<modes::PlanarSolution>& solution() const { return solution_; }

  protected:
    std::string kept_text() const override;
    jobs::Correction correction() const override;
    jobs::Area measured_area() const override;
    jobs::JobFrame target_frame() const override;
    jobs::KeptCorrection correction_of(const std::string& kept_text) const override;

  private:
    static constexpr const char* kKlipperBackup = "backup-printer.cfg";
    void read_klipper_settings(std::function<void(models::KlipperCartesian)> then);
    void apply_on_klipper_host(std::function<void(bool verify)> then);
    void save_klipper_skew(const std::string& backup, const std::function<void(bool verify)>& then);
    void restore_klipper_config(const std::string& backup, const std::string& why);
    std::string revert_on_klipper_host(int number, std::function<void(std::string what)> then);
    ReviewText klipper_review() const;

    models::MachineFile machine_;
    std::optional<models::KlipperCartesian> klipper_now_, klipper_sent_;
    std::optional<modes::FirmwareSettings> firmware_;
    std::optional<modes::PlanarMeasurement> measured_;
    std::optional<modes::PlanarSolution> solution_;
    // The measured photo, kept from measure to solve for the records' bed view.
    std::shared_ptr<const BedPhoto> bed_photo_;
    // G54's zero as the controller reported it before the target ran (grbl's $#).
    std::optional<geometry::Point2> controller_work_zero_;
};

// The planar overlay: each hole used (green; the fiducials labelled) and each extra blob (orange).
// PNG bytes.
std::string planar_overlay_png(const vision::GrayView& photo,
                               const modes::PlanarMeasurement& measured,
                               const models::MachineFile& machine,
                               const geometry::CameraModel& camera,
                               const geometry::BedPlane& plane);

}  // namespace calbox::firmware
