#pragma once
// The twin's photos kept between processes of one test run: a photo is a pure function of what
// is in view, the camera and the photo's settings (its noise seeded by the frame), and the suite
// rendered the same ones again and again (every fresh data directory photographs the same twelve
// calibration views). Where CALBOX_TWIN_PHOTO_CACHE names a directory (ctest sets one, emptied
// at the start of each run), a photo is stored there under a digest of everything it was made
// from and read back the next time the same inputs come; without it, every photo is rendered.
// The box's side never sees the difference: the bytes are the ones the renderer made.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "board/sim/camera_reference.hpp"
#include "board/sim/renderer.hpp"
#include "board/sim/scenes.hpp"

namespace calbox::sim {

// Everything a photo depends on, as bytes (each number as its exact bit pattern).
class PhotoKey {
  public:
    PhotoKey& add(double v);
    PhotoKey& add(std::int64_t v);
    PhotoKey& add(std::string_view text);
    PhotoKey& add(const Vec2& v) { return add(v.x).add(v.y); }
    PhotoKey& add(const Vec3& v) { return add(v.x).add(v.y).add(v.z); }
    PhotoKey& add(const Pose& pose);
    PhotoKey& add(const CameraIntrinsics& camera);
    PhotoKey& add(const PhotoSettings& photo);
    PhotoKey& add(const StrokeSurface& surface);
    PhotoKey& add(const std::vector<StrokeSegment>& strokes);
    PhotoKey& add(const std::vector<ReferenceMark>& marks);
    // 128 bits of digest, as 32 hex digits: the file's name.
    std::string digest() const;

  private:
    std::string bytes_;
};

// The photo kept for `key` in this run, if any (a damaged file is treated as none).
std::optional<GrayImage> kept_photo(const PhotoKey& key);
// Keeps `photo` for `key` (written whole, then renamed into place: side-by-side tests that
// render the same photo never read half of one). Nothing is kept without the directory.
void keep_photo(const PhotoKey& key, const GrayImage& photo);

}  // namespace calbox::sim
