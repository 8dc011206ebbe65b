// Inputs other people's cameras made (CALBOX_TEST_DATA/realworld, each folder's source, licence
// and reference values in its README), through the same calls the command line makes.
#include <CppUTest/TestHarness.h>

#include <algorithm>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "core/geometry/calibration.hpp"
#include "tests/support/test_data.hpp"

using namespace calbox;

namespace {

struct PhotoSet {
    std::vector<cv::Mat> images;
    std::vector<geometry::NamedImage> named;
};

PhotoSet photos_in(const std::string& folder) {
    std::vector<std::string> paths;
    for (const auto& e : std::filesystem::directory_iterator(test::test_data_path(folder)))
        if (e.path().extension() == ".jpg") paths.push_back(e.path().string());
    std::sort(paths.begin(), paths.end());
    PhotoSet set;
    for (const auto& p : paths) set.images.push_back(cv::imread(p, cv::IMREAD_GRAYSCALE));
    for (std::size_t i = 0; i < paths.size(); ++i) {
        const cv::Mat& m = set.images[i];
        set.named.push_back({std::filesystem::path(paths[i]).filename().string(),
                             {m.data, m.cols, m.rows, static_cast<int>(m.step)}});
    }
    return set;
}

// BoofCV's sets: chessboards of 5 x 7 squares (4 x 6 inner corners), 30 mm (the fisheye's in
// units of one square, which scales only the poses).
const geometry::PatternSpec kBoofBoard = geometry::parse_pattern_spec("chessboard:4x6@30");

geometry::CalibrationResult calibrate(const std::string& folder, geometry::LensModel model) {
    const auto set = photos_in("realworld/camera_calib/" + folder);
    return geometry::calibrate_camera(kBoofBoard, model, set.named);
}

void print(const char* what, const geometry::CalibrationResult& r) {
    const auto& c = r.camera;
    UT_PRINT((std::string(what) + ": fx " + std::to_string(c.fx()) + " fy " +
              std::to_string(c.fy()) + " cx " + std::to_string(c.cx()) + " cy " +
              std::to_string(c.cy()) + ", RMS " + std::to_string(c.rms_px) + " px over " +
              std::to_string(r.views.size()) + " views, " + std::to_string(r.dropped.size()) +
              " dropped")
                 .c_str());
}

}  // namespace

// The bounds: the focal lengths within 1.5 % of the folder's reference and the principal point
// within 6 px. Calibrations of one camera by two programs from one photo set differ by about a
// percent (on the Sony set OpenCV's own calibrateCamera gives 707.9 / 705.2 against BoofCV's
// 701.0 / 698.7); a wrong board size or corner order is off by far more.
TEST_GROUP(RealCamera){};

TEST(RealCamera, bumblebee2_left_calibrates_near_its_published_intrinsics) {
    const auto r = calibrate("boofcv_bumblebee2_left_chess", geometry::LensModel::pinhole);
    print("bumblebee2 left", r);
    CHECK_EQUAL(11u, r.views.size());
    DOUBLES_EQUAL(524.61, r.camera.fx(), 524.61 * 0.015);
    DOUBLES_EQUAL(526.92, r.camera.fy(), 526.92 * 0.015);
    DOUBLES_EQUAL(312.45, r.camera.cx(), 6);
    DOUBLES_EQUAL(247.40, r.camera.cy(), 6);
    CHECK(r.camera.rms_px < 0.3);
}

TEST(RealCamera, sony_hx5v_calibrates_near_boofcvs_intrinsics) {
    const auto r = calibrate("boofcv_sony_hx5v_chess", geometry::LensModel::pinhole);
    print("sony hx5v", r);
    CHECK_EQUAL(13u, r.views.size());
    DOUBLES_EQUAL(701.01, r.camera.fx(), 701.01 * 0.015);
    DOUBLES_EQUAL(698.65, r.camera.fy(), 698.65 * 0.015);
    DOUBLES_EQUAL(308.46, r.camera.cx(), 6);
    DOUBLES_EQUAL(246.84, r.camera.cy(), 6);
    CHECK(r.camera.rms_px < 0.3);
}

// The set that wrote a 37.5 px camera file: two views (4.jpg, 5.jpg) far off the other 22.
TEST(RealCamera, fisheye_set_drops_the_two_views_far_off_and_calibrates_under_half_a_pixel) {
    const auto r = calibrate("boofcv_fisheye_chess", geometry::LensModel::fisheye);
    print("fisheye", r);
    CHECK(r.camera.rms_px < 0.5);
    std::vector<std::string> dropped;
    for (const auto& d : r.dropped) dropped.push_back(d.name);
    std::sort(dropped.begin(), dropped.end());
    CHECK((dropped == std::vector<std::string>{"4.jpg", "5.jpg"}));
    CHECK_EQUAL(22u, r.views.size());
    for (const auto& v : r.views) CHECK_TEXT(v.rms_px < 1.0, v.name.c_str());
    // Each reason names the view's figure against the others'.
    CHECK(r.dropped.front().why.find("against the better views'") != std::string::npos);
}

TEST(RealCamera, a_pinhole_model_on_the_fisheye_lens_is_refused_for_its_rms) {
    try {
        calibrate("boofcv_fisheye_chess", geometry::LensModel::pinhole);
        FAIL("a pinhole calibration of a fisheye lens was accepted");
    } catch (const geometry::CalibrationError& e) {
        const std::string why = e.what();
        CHECK_TEXT(why.find("pinhole calibration reprojects at") != std::string::npos, e.what());
        CHECK_TEXT(why.find("at most 1.00 px") != std::string::npos, e.what());
    }
}

TEST(RealCamera, too_few_views_left_once_the_far_ones_are_dropped_is_refused) {
    auto set = photos_in("realworld/camera_calib/boofcv_fisheye_chess");
    std::vector<geometry::NamedImage> four;
    for (const auto& n : set.named)
        if (n.name == "4.jpg" || n.name == "5.jpg" || n.name == "6.jpg" || n.name == "7.jpg")
            four.push_back(n);
    CHECK_EQUAL(4u, four.size());
    try {
        geometry::calibrate_camera(kBoofBoard, geometry::LensModel::fisheye, four);
        FAIL("two views were enough for a fisheye");
    } catch (const geometry::CalibrationError& e) {
        const std::string why = e.what();
        CHECK_TEXT(why.find("set aside") != std::string::npos, e.what());
        CHECK_TEXT(why.find("at least 4 views") != std::string::npos, e.what());
    }
}
