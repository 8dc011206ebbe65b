#pragma once
// The live view a person aims and focuses the box by: the camera's frame, scaled down, with the
// set-up guide drawn over it (the board views' coverage so far, the bed's expected outline, what
// is clipped white or black, with what to do) and a sharpness figure. JPEG bytes, so that OpenCV
// stays out of this header.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "hal/camera.hpp"

namespace calbox::firmware {

struct LiveGuide {
    // Both from the set-up (camera.yaml, plane.yaml); without them no outline is drawn.
    std::optional<geometry::CameraModel> camera;
    std::optional<geometry::BedPlane> plane;
    // The bed as the machine file gives it: a delta's printable radius, else its work area.
    double bed_radius_mm = 0;
    double bed_size_x_mm = 0, bed_size_y_mm = 0;
    // Each set-up view's board corners, and the image they cover together.
    std::vector<std::vector<geometry::Point2>> views;
    double coverage = 0;
};

struct LiveImage {
    std::string jpeg;
    // The variance of the Laplacian over the frame's middle, full resolution: higher is
    // sharper; a figure to turn the focus ring by, not an absolute.
    double sharpness = 0;
    // Of the frame: clipped white (marked red, with what to do: tilt the board, diffuse the
    // lamp's light) and black (marked blue: more light there).
    double clipped_share = 0;
    double black_share = 0;
    int width_px = 0, height_px = 0;
    std::uint64_t sequence = 0;  // the frame's
};

// Throws std::invalid_argument for an empty frame.
LiveImage live_view(const hal::Frame& frame, const LiveGuide& guide, int max_width_px);

// The newest frame, handed from the loop's thread (the camera) to the server's (the live view):
// one copy, shared by every viewer (a 12 MP frame per viewer would be hundreds of megabytes).
class LatestFrame {
  public:
    void put(const hal::Frame& frame);
    // Waits up to `within` for a frame numbered past `after`, holding none: a viewer waiting
    // keeps no frame alive.
    void wait_past(std::uint64_t after, std::chrono::milliseconds within);
    std::shared_ptr<const hal::Frame> newest();

  private:
    std::mutex mutex_;
    std::condition_variable arrived_;
    std::shared_ptr<const hal::Frame> frame_;
    std::uint64_t count_ = 0;  // frames put: each frame's number here
};

// The live view drawn once per frame for all its viewers: one drawing at a time, of the newest
// frame when it starts; the others wait for it, holding no frame, and are given the same image.
// So however many viewers and however slowly they are served, the frames alive are the newest,
// the one being drawn and the one being put.
class SharedLiveView {
  public:
    // nullptr while the camera has given no frame. Drawn again when the frame or the guide (a
    // new set-up view, the camera or the bed's plane found) has changed since the last drawing.
    std::shared_ptr<const LiveImage> of_newest(LatestFrame& frames, const LiveGuide& guide,
                                               int max_width_px);

  private:
    std::mutex mutex_;
    std::shared_ptr<const LiveImage> newest_;  // under mutex_, with its frame's sequence
    std::string drawn_guide_;                  // under mutex_: what newest_'s guide showed
};

}  // namespace calbox::firmware
