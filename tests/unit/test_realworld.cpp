// Inputs other people's cameras made (CALBOX_TEST_DATA/realworld, each folder's source, licence
// and reference values in its README), through the same calls the command line makes.
#include "tests/unit/realworld_inputs.hpp"

// The bounds: the focal lengths within 1.5 % of the folder's reference and the principal point
// within 6 px. Calibrations of one camera by two programs from one photo set differ by about a
// percent (on the Sony set OpenCV's own calibrateCamera gives 707.9 / 705.2 against BoofCV's
// 701.0 / 698.7); a wrong board size or corner order is off by far more.
TEST_GROUP(RealCamera){};

// Other people's cameras' JPEGs (EXIF, thumbnails, a fisheye's) read by the box's own reader as
// OpenCV reads them, pixel for pixel (the box's binary no longer links OpenCV's imgcodecs).
TEST(RealCamera, every_photo_reads_as_opencv_reads_it) {
    int read = 0;
    for (const auto& e :
         std::filesystem::recursive_directory_iterator(test::test_data_path("realworld"))) {
        const auto ext = e.path().extension().string();
        if (ext != ".jpg" && ext != ".png") continue;
        std::ifstream in(e.path(), std::ios::binary);
        const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                              std::istreambuf_iterator<char>());
        const cv::Mat theirs = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
        const auto ours = vision::decode_gray(bytes);
        CHECK_EQUAL(theirs.cols, ours.width_px);
        CHECK_EQUAL(theirs.rows, ours.height_px);
        const cv::Mat view(ours.height_px, ours.width_px, CV_8UC1,
                           const_cast<std::uint8_t*>(ours.pixels.data()));
        CHECK_TEXT(cv::norm(theirs, view, cv::NORM_INF) == 0, e.path().string().c_str());
        ++read;
    }
    CHECK_EQUAL(50, read);
}

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

// 22.jpg: the board seen edge-on at the fisheye's rim, bright screens beside it. SB finds no
// board; the search through the equalised image (for a board under a glare) put a 4x6 grid across
// the wrong squares there, and that view stopped OpenCV's fisheye calibration. The board is not
// under a glare, so that search's find is not taken.
TEST(RealCamera, a_view_beside_bright_screens_gives_no_board_made_up_by_equalising) {
    const cv::Mat photo =
        cv::imread(test::test_data_path("realworld/camera_calib/boofcv_fisheye_chess/22.jpg"),
                   cv::IMREAD_GRAYSCALE);
    CHECK_FALSE(photo.empty());
    const auto found = geometry::find_board(
        kBoofBoard, {photo.data, photo.cols, photo.rows, static_cast<int>(photo.step)});
    CHECK_FALSE(found.has_value());
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

// G-code other people's slicers and CAM programs wrote (realworld/gcode), through a correction
// a little off the identity: each file compensated, or refused for a reason a CAM user reads.
TEST_GROUP(RealGcode){};

TEST(RealGcode, every_file_is_compensated_or_refused_for_a_reason_a_cam_user_reads) {
    // What each file is: compensated (""), or refused with these words.
    const std::map<std::string, std::string> expected = {
        {"cnc/fusion360/1070_wall_27bit.nc", ""},
        {"cnc/jsdc.gcode", ""},
        {"cnc/linuxcnc/arcspiral.ngc", ""},
        {"cnc/linuxcnc/g76.ngc", "a lathe job"},
        {"cnc/linuxcnc/hole-circle.ngc", ""},
        {"cnc/linuxcnc/tort.ngc", ""},
        {"cnc/ugs/ShapeOko_Calibration_Pattern_01b.ngc", ""},
        {"cnc/ugs/arc_rword_test.gcode", ""},
        {"laser/input5.gcode", ""},
        {"printer/gcode-preview_plant-sign_prusaslicer274_arcs.gcode", ""},
        {"printer/gcode-preview_puzzle_all_cura231.gcode", ""},
        {"printer/gcode-preview_vase_prusaslicer274.gcode", ""},
    };
    int compensated = 0, refused = 0;
    for (const auto& [file, refusal] : expected) {
        const std::string job = test::read_test_data("realworld/gcode/" + file);
        jobs::CompensateReport report;
        std::string out, why;
        try {
            out = jobs::compensate_gcode(job, {kSlightlyOff, {}}, frame_of_file(file), {}, report);
        } catch (const jobs::CompensateError& e) {
            why = e.what();
        }
        UT_PRINT((file + ": " +
                  (why.empty() ? "compensated, " + std::to_string(report.moves) + " moves, " +
                                     std::to_string(report.arcs) + " arcs"
                               : "refused: " + why))
                     .c_str());
        if (why.empty()) {
            ++compensated;
            CHECK_TEXT(refusal.empty(), file.c_str());
            // Every non-motion line kept, in order (a program LinuxCNC evaluates, or one whose
            // drilling cycles repeat, is checked hole by hole on its own).
            if (report.ran_program || report.holes > 0) continue;
            const auto in = kept_lines(job, false), kept = kept_lines(out, true);
            CHECK_TEXT(in == kept, (file + ": " + std::to_string(in.size()) + " lines in, " +
                                    std::to_string(kept.size()) + " kept")
                                       .c_str());
        } else {
            ++refused;
            CHECK_TEXT(!refusal.empty() && why.find(refusal) != std::string::npos, why.c_str());
        }
    }
    UT_PRINT((std::to_string(compensated) + " compensated, " + std::to_string(refused) + " refused")
                 .c_str());
}

namespace {

// Segments by the cells of a grid they cross: the distance from a point to a path of tens of
// thousands of segments, in a few of them.
class PathIndex {
  public:
    explicit PathIndex(const std::vector<std::pair<geometry::Point2, geometry::Point2>>& segments)
        : segments_(segments) {
        for (std::size_t i = 0; i < segments_.size(); ++i) {
            const auto& [a, b] = segments_[i];
            for (long x = cell(std::min(a.x, b.x)); x <= cell(std::max(a.x, b.x)); ++x)
                for (long y = cell(std::min(a.y, b.y)); y <= cell(std::max(a.y, b.y)); ++y)
                    cells_[{x, y}].push_back(i);
        }
    }
    double distance(geometry::Point2 p) const {
        double best = 1e300;
        for (long dx = -1; dx <= 1; ++dx)
            for (long dy = -1; dy <= 1; ++dy) {
                const auto it = cells_.find({cell(p.x) + dx, cell(p.y) + dy});
                if (it == cells_.end()) continue;
                for (const std::size_t i : it->second) {
                    const auto& [a, b] = segments_[i];
                    const double vx = b.x - a.x, vy = b.y - a.y, len2 = vx * vx + vy * vy;
                    const double t =
                        len2 > 0
                            ? std::clamp(((p.x - a.x) * vx + (p.y - a.y) * vy) / len2, 0.0, 1.0)
                            : 0;
                    best = std::min(best, std::hypot(a.x + t * vx - p.x, a.y + t * vy - p.y));
                }
            }
        return best;
    }

  private:
    static long cell(double v) { return static_cast<long>(std::floor(v / kCellMm)); }
    static constexpr double kCellMm = 2;
    std::vector<std::pair<geometry::Point2, geometry::Point2>> segments_;
    std::map<std::pair<long, long>, std::vector<std::size_t>> cells_;
};

std::vector<std::pair<geometry::Point2, geometry::Point2>> segments_of(
    const std::vector<test::ReferenceMove>& moves, const jobs::Correction& through) {
    std::vector<std::pair<geometry::Point2, geometry::Point2>> out;
    for (const auto& m : moves)
        for (std::size_t k = 1; k < m.path_mm.size(); ++k)
            out.emplace_back(through(m.path_mm[k - 1]), through(m.path_mm[k]));
    return out;
}

}  // namespace

// The compensated files' motion against the input's motion sent through the correction, each
// read by the tests' own reading (tests/support/gcode_reference.hpp): every point the output
// reaches lies on the corrected input path, and every point of the input path, corrected, on the
// output's, within the compensator's own arc tolerance of 0.002 mm (and its 0.0001 mm digits).
TEST(RealGcode, a_compensated_files_motion_is_the_inputs_through_the_correction) {
    const jobs::Correction identity = [](geometry::Point2 p) { return p; };
    // Each job placed with its work zero at machine (40, -25): the correction is the machine's,
    // so the job's point p goes to kSlightlyOff(p + W) - W (not kSlightlyOff(p), which a job
    // compensated in the wrong frame would show, up to 0.05 mm off here).
    const geometry::Point2 w{40, -25};
    const jobs::Correction through_machine = [w](geometry::Point2 p) {
        const auto c = kSlightlyOff({p.x + w.x, p.y + w.y});
        return geometry::Point2{c.x - w.x, c.y - w.y};
    };
    double worst = 0;
    for (const char* file :
         {"cnc/fusion360/1070_wall_27bit.nc", "cnc/jsdc.gcode", "cnc/linuxcnc/arcspiral.ngc",
          "cnc/linuxcnc/tort.ngc", "cnc/ugs/ShapeOko_Calibration_Pattern_01b.ngc",
          "cnc/ugs/arc_rword_test.gcode", "laser/input5.gcode",
          "printer/gcode-preview_plant-sign_prusaslicer274_arcs.gcode",
          "printer/gcode-preview_puzzle_all_cura231.gcode",
          "printer/gcode-preview_vase_prusaslicer274.gcode"}) {
        const std::string job = test::read_test_data(std::string("realworld/gcode/") + file);
        jobs::CompensateReport report;
        const std::string out =
            jobs::compensate_gcode(job, {kSlightlyOff, {}}, frame_of_file(file, w), {}, report);
        const auto in_moves = test::reference_motion(job);
        const auto out_moves = test::reference_motion(out);
        const PathIndex input_corrected(segments_of(in_moves, through_machine));
        const PathIndex output(segments_of(out_moves, identity));
        double off_input = 0, off_output = 0;
        for (const auto& m : out_moves)
            for (std::size_t k = m.start_known ? 0 : 1; k < m.path_mm.size(); ++k)
                off_input = std::max(off_input, input_corrected.distance(m.path_mm[k]));
        for (const auto& m : in_moves)
            for (std::size_t k = m.start_known ? 0 : 1; k < m.path_mm.size(); ++k)
                off_output = std::max(off_output, output.distance(through_machine(m.path_mm[k])));
        UT_PRINT((std::string(file) + ": " + std::to_string(in_moves.size()) + " moves in, " +
                  std::to_string(out_moves.size()) + " out; the output off the corrected input " +
                  number_text("%.5f", off_input) + " mm, the corrected input off the output " +
                  number_text("%.5f", off_output) + " mm")
                     .c_str());
        worst = std::max({worst, off_input, off_output});
        CHECK_TEXT(off_input <= 0.0021 && off_output <= 0.0021, file);
    }
    UT_PRINT(("worst " + number_text("%.5f", worst) + " mm").c_str());
}

// LinuxCNC's hole-circle.ngc: six holes drilled round a 1.5 inch radius by an incremental G81
// repeated with polar words (G91 ... ^60 L6). Each hole, worked by hand at 60 k degrees on that
// circle about the work zero, comes out through the correction as LinuxCNC keeps the cycle.
TEST(RealGcode, a_bolt_circle_in_polar_words_drills_each_hole_through_the_correction) {
    const std::string job = test::read_test_data("realworld/gcode/cnc/linuxcnc/hole-circle.ngc");
    const geometry::Point2 w{150, 150};
    jobs::CompensateReport report;
    const std::string out = jobs::compensate_gcode(
        job, {kSlightlyOff, {}}, frame_of_file("cnc/linuxcnc/hole-circle.ngc", w), {}, report);
    CHECK_EQUAL(6, report.holes);
    std::istringstream lines(out);
    geometry::Point2 at_in{};  // the written position, inches, in the job's frame
    bool incremental = false;
    int hole = 0;
    for (std::string raw; std::getline(lines, raw);) {
        const auto line = gcode::parse_line(raw);
        bool g91 = line.is('G', 91), g90 = line.is('G', 90), g81 = line.is('G', 81);
        for (const auto& word : line.parameters)
            if (word.letter == 'G' && word.value) {
                g91 = g91 || *word.value == 91;
                g90 = g90 || *word.value == 90;
                g81 = g81 || *word.value == 81;
            }
        if (g91) incremental = true;
        if (g90) incremental = false;
        if (!line.has('X') && !line.has('Y')) continue;
        const double x = line.value('X').value_or(incremental ? 0 : at_in.x);
        const double y = line.value('Y').value_or(incremental ? 0 : at_in.y);
        at_in = incremental ? geometry::Point2{at_in.x + x, at_in.y + y} : geometry::Point2{x, y};
        if (!g81) continue;
        ++hole;
        const double a = hole * 60 * 3.14159265358979323846 / 180;
        const geometry::Point2 machine{1.5 * 25.4 * std::cos(a) + w.x,
                                       1.5 * 25.4 * std::sin(a) + w.y};
        const auto c = kSlightlyOff(machine);
        DOUBLES_EQUAL(c.x - w.x, at_in.x * 25.4, 0.002);
        DOUBLES_EQUAL(c.y - w.y, at_in.y * 25.4, 0.002);
    }
    CHECK_EQUAL(6, hole);
}
