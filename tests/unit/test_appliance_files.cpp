// The appliance's link to the printer (banners, grbl, a noisy line, the live view beside the
// cycle) and its files (saved photos, a full disk, the records kept and pruned).
#include "tests/unit/appliance_rig.hpp"

TEST_GROUP(ApplianceLink){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

// The twin's banner goes out as soon as anyone opens the line; a line the box has opened but
// not yet made raw must not echo it back to the printer as a G-code line.
TEST(ApplianceLink, the_printers_banner_is_not_echoed_back_before_the_line_is_raw) {
    auto bench = std::make_shared<sim::TwinBench>(sim::load_scenario(kScenario.string()));
    sim::TwinPrinterLink link(bench);
    const int slave = ::open(link.device_path().c_str(), O_RDWR | O_NOCTTY);
    CHECK(slave >= 0);
    char banner[64] = {};
    std::size_t got = 0;
    for (int i = 0; i < 100 && got < 6; ++i) {
        pollfd p{slave, POLLIN, 0};
        if (::poll(&p, 1, 20) == 1) {
            const ssize_t n = ::read(slave, banner + got, sizeof banner - 1 - got);
            if (n > 0) got += static_cast<std::size_t>(n);
        }
    }
    STRCMP_CONTAINS("start", banner);
    ::usleep(200000);  // the printer's thread has read whatever came back by now
    CHECK_EQUAL(0u, link.lines_received());
    ::close(slave);
}

// The twin as grbl: its own welcome, not Marlin's; a numbered, checksummed line is its error:1
// (a word without its letter), M110 its error:20, a plain line an ok; a move beyond the travel
// its soft-limit alarm, after which it is locked (error:9).
TEST(ApplianceLink, a_grbl_twin_greets_and_answers_as_grbl) {
    auto bench = std::make_shared<sim::TwinBench>(sim::load_scenario(
        (fs::path(CALBOX_SOURCE_DIR) / "tests/scenarios/planar_small.toml").string()));
    sim::TwinPrinterLink link(bench);
    const int slave = ::open(link.device_path().c_str(), O_RDWR | O_NOCTTY);
    CHECK(slave >= 0);
    termios raw{};
    ::tcgetattr(slave, &raw);
    ::cfmakeraw(&raw);
    ::tcsetattr(slave, TCSANOW, &raw);
    std::string heard;
    const auto hear_line = [&] {
        for (int i = 0; i < 200 && heard.find('\n') == std::string::npos; ++i) {
            pollfd p{slave, POLLIN, 0};
            char buffer[256];
            if (::poll(&p, 1, 20) == 1) {
                const ssize_t n = ::read(slave, buffer, sizeof buffer);
                if (n > 0) heard.append(buffer, static_cast<std::size_t>(n));
            }
        }
        const auto end = heard.find('\n');
        const std::string line = heard.substr(0, end);
        heard.erase(0, end == std::string::npos ? heard.size() : end + 1);
        return line;
    };
    const auto say = [&](const std::string& line) {
        const std::string text = line + "\n";
        CHECK_EQUAL(static_cast<ssize_t>(text.size()), ::write(slave, text.data(), text.size()));
        return hear_line();
    };
    STRCMP_EQUAL("Grbl 1.1h ['$' for help]", hear_line().c_str());
    STRCMP_EQUAL("error:1", say("N1 G21*19").c_str());
    STRCMP_EQUAL("error:20", say("M110 N0").c_str());
    STRCMP_EQUAL("ok", say("G21").c_str());
    STRCMP_EQUAL("ALARM:2", say("G0 X5000 Y0").c_str());
    STRCMP_EQUAL("error:9", say("G21").c_str());
    ::close(slave);
}

// Line noise on the pty: the printer refuses corrupted lines, the box resends, the cycle ends
// as on a clean link.
TEST(ApplianceLink, a_noisy_link_is_resent_line_by_line_and_the_cycle_completes) {
    Rig rig(prepared_dir("noise"), scenario_with("noise", "[faults]\nline_noise = 0.05"), {});
    rig.run_cycle();
    rig.check_cycles_completed(1);
    std::size_t resent = 0;
    const auto t = rig.transcript();
    for (std::size_t i = 1; i < t.size(); ++i)
        if (t[i] == t[i - 1]) ++resent;
    UT_PRINT(
        ("lines resent after noise: " + std::to_string(resent) + " of " + std::to_string(t.size()))
            .c_str());
    CHECK(resent > 50);
    const auto after = rig.board.bench->judge_delta_printer();
    CHECK(after.xy_rms <= 0.01);
}

// From an empty data directory: the set-up asks for the board views and the plane first.
TEST(ApplianceLink, the_first_cycle_runs_the_set_up_from_photos) {
    const fs::path& dir = prepared_setup();
    CHECK(fs::exists(dir / "camera.yaml"));
    std::ifstream camera(dir / "camera.yaml");
    std::stringstream text;
    text << camera.rdbuf();
    STRCMP_CONTAINS("camera_matrix", text.str().c_str());
}

// The twin's camera, each frame it gives also saved as the next numbered PNG.
struct RecordingCamera final : hal::Camera {
    hal::Camera* twin = nullptr;
    fs::path dir;
    int saved = 0;
    void start_capture(const hal::CaptureRequest& request) override {
        twin->start_capture(request);
    }
    int completion_fd() const override { return twin->completion_fd(); }
    hal::CaptureResult take_frames() override {
        auto result = twin->take_frames();
        for (const auto& frame : result.frames) {
            char name[16];
            std::snprintf(name, sizeof name, "%04d.png", ++saved);
            drivers::write_frame_png(dir / name, frame);
        }
        return result;
    }
};

TEST_GROUP(ApplianceFiles){void setup() override{mock().ignoreOtherCalls();
}
void teardown() override {
    mock().clear();
}
}
;

// A cycle re-run on the photos a first cycle saved (--camera-files): the same measurements, so
// the same correction and verification, and the second twin printer, which never showed its
// print to a camera, ends as well calibrated as the first.
TEST(ApplianceFiles, a_cycle_runs_whole_on_saved_photos) {
    const fs::path photos = fresh_dir("photos");
    RecordingCamera recorder;
    recorder.dir = photos;
    std::optional<std::vector<std::string>> first_commands;
    std::optional<double> first_verify;
    {
        Rig first(prepared_dir("files_first"), kScenario.string(), {},
                  [&recorder](sim::SimBoard& board) -> hal::Camera& {
                      recorder.twin = board.camera;
                      return recorder;
                  });
        first.run_cycle();
        first.check_cycles_completed(1);
        first_commands = delta_of(first.cycle).solution()->commands;
        first_verify = first.cycle.report().verified->rms_mm;
    }
    // the camera check, the target, the verification prints of the two passes that sent something
    CHECK_EQUAL(4, recorder.saved);

    drivers::FileCamera files(photos.string());
    auto use_files = [&files](sim::SimBoard&) -> hal::Camera& { return files; };
    Rig second(prepared_dir("files_second"), kScenario.string(), {}, use_files);
    second.run_cycle();
    second.check_cycles_completed(1);
    CHECK_EQUAL(0, second.board.camera->captures_started());  // the twin's camera never used
    // Photos from files say nothing of their exposure: not metered, and said.
    CHECK(std::any_of(second.log.begin(), second.log.end(), [](const std::string& line) {
        return line.find("target: exposure the camera's own; ") != std::string::npos &&
               line.find("the camera does not report its exposure: taken at its own") !=
                   std::string::npos;
    }));
    CHECK(delta_of(second.cycle).solution()->commands == *first_commands);
    DOUBLES_EQUAL(*first_verify, second.cycle.report().verified->rms_mm, 1e-12);
    const auto after = second.board.bench->judge_delta_printer();
    CHECK(after.xy_rms <= 0.0045);
    CHECK(after.xy_max <= 0.0105);
}

TEST(ApplianceFiles, photos_of_another_size_than_the_calibration_stop_with_one_line) {
    const fs::path photos = fresh_dir("small_photos");
    hal::Frame small;
    small.width_px = 640;
    small.height_px = 480;
    small.stride_bytes = 640;
    small.pixels.assign(640 * 480, 128);
    drivers::write_frame_png(photos / "0001.png", small);
    drivers::FileCamera files(photos.string());
    Rig rig(prepared_dir("files_small"), kScenario.string(), {},
            [&files](sim::SimBoard&) -> hal::Camera& { return files; });
    rig.run_cycle();
    CHECK(rig.cycle.state() == firmware::CycleState::error);
    STRCMP_CONTAINS("the photo is 640x480, the camera was calibrated at 2028x1520 (camera.yaml)",
                    rig.cycle.error().c_str());
}

TEST(ApplianceFiles, a_source_without_photos_and_photos_running_out_are_errors) {
    const fs::path empty = fresh_dir("no_photos");
    CHECK_THROWS(std::runtime_error, drivers::FileCamera(empty.string()));
    const fs::path one = fresh_dir("one_photo");
    hal::Frame frame;
    frame.width_px = 8;
    frame.height_px = 4;
    frame.stride_bytes = 8;
    frame.pixels.assign(32, 7);
    drivers::write_frame_png(one / "a.png", frame);
    drivers::FileCamera files((one / "*.png").string());
    files.start_capture({2, {}, {}});
    pollfd p{files.completion_fd(), POLLIN, 0};
    CHECK_EQUAL(1, ::poll(&p, 1, 5000));
    const auto result = files.take_frames();
    STRCMP_CONTAINS("no photo left (all 1 used)", result.error.c_str());

    // A photo the box's user may not read (mode 0600, owned by root): one line, naming it.
    fs::permissions(one / "a.png", fs::perms::owner_read | fs::perms::owner_write);
    const std::string denied = test::error_as_unprivileged_user([&] {
        drivers::FileCamera mine(one.string());
        mine.start_capture({1, {}, {}});
        pollfd q{mine.completion_fd(), POLLIN, 0};
        ::poll(&q, 1, 5000);
        throw std::runtime_error(mine.take_frames().error);
    });
    STRCMP_CONTAINS(((one / "a.png").string() + ": cannot read: Permission denied").c_str(),
                    denied.c_str());
}

// A galvo scanner under the box (issue 17): the grid burned over the link, measured, the table
// kept by the box, the grid burned through it to verify, and revert putting the previous (no)
// table back. Half-size camera; the set-up from photos as on a real box.
// The data directory's disk, filling up when the test says: every write then fails as a full
// disk's does (ENOSPC), after part of the bytes went in.
struct FillingDisk final : drivers::FileSystemCalls {
    bool full = false;
    drivers::FileSystemCalls& real = drivers::posix_file_system();
    int create_truncated(const fs::path& p, drivers::FileAccess access) override {
        return real.create_truncated(p, access);
    }
    void write_all(int h, std::string_view bytes) override {
        if (!full) return real.write_all(h, bytes);
        real.write_all(h, bytes.substr(0, bytes.size() / 2));
        errno = ENOSPC;
        throw std::runtime_error("cannot write " + std::to_string(h) + ": " + std::strerror(errno));
    }
    void flush(int h) override { real.flush(h); }
    void close(int h) override { real.close(h); }
    void rename(const fs::path& a, const fs::path& b) override { real.rename(a, b); }
    void flush_directory(const fs::path& d) override { real.flush_directory(d); }
    void remove(const fs::path& p) noexcept override { real.remove(p); }
};

TEST(ApplianceFiles, a_full_disk_stops_the_cycle_with_nothing_half_written_and_nothing_sent) {
    FillingDisk disk;
    Rig rig(prepared_dir("full_disk"), kScenario.string(), {}, {}, disk);
    const auto before = rig.board.bench->judge_delta_printer();
    disk.full = true;
    rig.run_cycle();
    CHECK(rig.cycle.state() == firmware::CycleState::error);
    STRCMP_CONTAINS("records: cannot write", rig.cycle.error().c_str());
    STRCMP_CONTAINS("No space left on device", rig.cycle.error().c_str());
    for (const auto& line : rig.transcript()) {
        CHECK_TEXT(command_of(line).rfind("M665", 0) != 0 && command_of(line).rfind("M500", 0) != 0,
                   ("sent with a full disk: " + line).c_str());
    }
    for (const auto& entry : fs::directory_iterator(rig.dir)) {
        const auto name = entry.path().filename().string();
        CHECK_TEXT(name.find(".tmp") == std::string::npos, ("left behind: " + name).c_str());
        CHECK_TEXT(name.rfind("cycle-0001-", 0) != 0, ("half a record: " + name).c_str());
    }
    const auto after = rig.board.bench->judge_delta_printer();
    DOUBLES_EQUAL(before.xy_rms, after.xy_rms, 1e-12);  // the printer's geometry as it was
    check_error_state(rig, "No space left on device");
}

// A cycle's record: measurements, result, backup, its photos (records.keep_photos) and every
// display frame it showed; older records pruned past the count, then past the size.
TEST(ApplianceFiles, each_cycle_leaves_a_record_and_old_ones_are_pruned) {
    const fs::path dir = prepared_dir("records");
    for (int n : {1, 2, 3}) {
        char name[40];
        std::snprintf(name, sizeof name, "cycle-%04d-result.json", n);
        std::ofstream(dir / name) << "{}\n";
    }
    fs::resize_file(dir / "cycle-0002-result.json", 50'000'000);  // sparse: 50 MB on paper
    std::ofstream(dir / "last-cycle") << "3\n";
    std::ofstream(dir / "cycle-notes.txt") << "not a record\n";
    firmware::CycleSettings settings;
    settings.records = {3, 30'000'000, true};
    Rig rig(dir, kScenario.string(), settings);
    rig.run_cycle();
    rig.check_cycles_completed(1);
    CHECK_EQUAL(4, rig.cycle.report().number);
    std::uintmax_t newest_bytes = 0;
    int screens = 0;
    for (const auto& entry : fs::directory_iterator(dir)) {
        const auto name = entry.path().filename().string();
        if (name.rfind("cycle-0004-", 0) == 0) newest_bytes += entry.file_size();
        if (name.rfind("cycle-0004-screen-", 0) == 0) ++screens;
    }
    UT_PRINT(("the newest record: " + std::to_string(newest_bytes) + " bytes").c_str());
    CHECK_TEXT(newest_bytes < 25'000'000, "the newest record alone is too big for this test");
    CHECK_FALSE(fs::exists(dir / "cycle-0001-result.json"));  // past the count of 3
    CHECK_FALSE(fs::exists(dir / "cycle-0002-result.json"));  // past 30 MB
    CHECK_TRUE(fs::exists(dir / "cycle-0003-result.json"));
    CHECK_TRUE(fs::exists(dir / "cycle-notes.txt"));
    for (const char* f :
         {"measurements.json", "result.json", "backup.gcode", "verify-measurements.json",
          "target-photo-1.png", "verify-photo-1.png", "overlay.png", "verify-overlay.png",
          "pass-2-result.json", "pass-2-backup.gcode", "pass-2-verify-measurements.json",
          "pass-2-verify-photo-1.png", "pass-2-verify-overlay.png", "error-field.png",
          "pass-2-error-field.png"})
        CHECK_TEXT(fs::exists(dir / ("cycle-0004-" + std::string(f))), f);
    const cv::Mat photo =
        cv::imread((dir / "cycle-0004-target-photo-1.png").string(), cv::IMREAD_UNCHANGED);
    CHECK_EQUAL(2028, photo.cols);
    CHECK_EQUAL(1520, photo.rows);
    CHECK_EQUAL(CV_8UC1, photo.type());
    const cv::Mat overlay = cv::imread((dir / "cycle-0004-overlay.png").string(), cv::IMREAD_COLOR);
    CHECK_EQUAL(2028, overlay.cols);  // drawn on the first photo
    // Every frame the display showed from the start to the done screen.
    CHECK_TRUE(screens >= 10);
    const cv::Mat last_screen =
        cv::imread((dir / ("cycle-0004-screen-" + std::string(screens < 10 ? "0" : "") +
                           std::to_string(screens) + ".png"))
                       .string(),
                   cv::IMREAD_GRAYSCALE);
    CHECK_EQUAL(128, last_screen.cols);
    CHECK_EQUAL(64, last_screen.rows);
}

// The live view shares the camera with the cycle: a preview while the cycle's own capture runs is
// refused, and a capture the cycle asks for while a preview runs waits for it, so that every
// photo the cycle measures is its own; each frame reaches on_frame.
TEST(ApplianceLink, the_live_views_frames_never_take_the_cycles_place) {
    Rig rig(fresh_dir("preview"), kScenario.string(), {});
    std::vector<std::uint64_t> frames;
    const auto listening = rig.cycle.subscribe(
        {{}, {}, {}, {}, [&](const hal::Frame& f) { frames.push_back(f.metadata.sequence); }});
    CHECK_TRUE(rig.cycle.preview());
    CHECK_FALSE(rig.cycle.preview());  // one at a time
    rig.run_until([&] { return frames.size() == 1; });
    // A preview asked for, then the set-up's first view pressed at once: its capture waits.
    bool pressed = false;
    rig.intercept = [&](firmware::Prompt p) {
        if (p != firmware::Prompt::hold_calibration_board || pressed) return false;
        pressed = true;
        CHECK_TRUE(rig.cycle.preview());
        firmware::act_on_prompt(*rig.board.bench, *rig.board.lines, p, 0);
        return true;
    };
    CHECK_EQUAL(std::string(), rig.cycle.calibrate_camera());
    rig.run_until([&] {
        return std::any_of(rig.log.begin(), rig.log.end(), [](const std::string& l) {
            return l.find("view 1/") != std::string::npos && l.find("corners") != std::string::npos;
        });
    });
    // The preview's frame, then the cycle's: two more, and the view measured the cycle's.
    CHECK_EQUAL(3u, frames.size());
    const auto view = std::find_if(rig.log.begin(), rig.log.end(), [](const std::string& l) {
        return l.find("view 1/") != std::string::npos && l.find("corners") != std::string::npos;
    });
    STRCMP_CONTAINS("88 corners", view->c_str());
    rig.intercept = nullptr;
    rig.cycle.cancel("test over");
}
