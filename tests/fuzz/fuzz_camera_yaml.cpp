// Fuzz target: camera.yaml, plane.yaml and reference.yaml (OpenCV FileStorage YAML). The first
// byte chooses the reader, the rest is the file.
#include "core/geometry/calibration.hpp"
#include "core/geometry/camera_model.hpp"
#include "core/vision/reference_marks.hpp"
#include "tests/fuzz/fuzz_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    const std::string text(calbox::fuzz::as_text(data + 1, size - 1));
    try {
        switch (data[0] % 3) {
            case 0:
                calbox::geometry::camera_from_yaml(text);
                break;
            case 1:
                calbox::geometry::plane_from_yaml(text);
                break;
            default:
                calbox::vision::reference_from_yaml(text);
                break;
        }
    } catch (const calbox::geometry::FileFormatError&) {
    }
    return 0;
}
