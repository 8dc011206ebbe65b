#pragma once
// The sim board: hal devices bound to the digital twin. The printer answers G-code behind a
// pseudo-terminal (so the real termios driver and the host protocol run), the camera renders
// what the printer laid down or the board a person holds, the lines and LEDs are events, the
// display writes PNG files. The box's side sees only these devices; the judge alone reads the
// twin's truth.
#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "board/devices.hpp"
#include "board/sim/delta_judge.hpp"
#include "board/sim/galvo_twin.hpp"
#include "board/sim/router_twin.hpp"
#include "board/sim/scenario.hpp"
#include "drivers/tls.hpp"
#include "hal/background_job.hpp"
#include "hal/camera.hpp"
#include "hal/clock.hpp"
#include "hal/display.hpp"
#include "hal/lines.hpp"
#include "hal/log.hpp"
#include "hal/notifier.hpp"
#include "hal/serial_port.hpp"

namespace calbox::sim {

// What lies under and in front of the camera, and the printer that makes it: the one world the
// sim board's devices and its operator share (thread-safe: the printer's link and the camera
// run on threads of their own).
class TwinBench {
  public:
    // `settings_file`, when given, keeps what the printer stores (M500) from one run to the next,
    // as its EEPROM does: loaded at power-on, rewritten at each M500.
    explicit TwinBench(Scenario scenario, std::filesystem::path settings_file = {});
    const Scenario& scenario() const { return scenario_; }

    // The printer executes one line it received; returns what it reports (M503), throws
    // JobError for a line it refuses.
    std::vector<std::string> run_printer_line(std::string_view line);
    void reset_printer();  // a power cycle or watchdog reset: unhomed, job state gone
    // A delta printer's geometry as its firmware holds it now, and a restart that gives it
    // another (Klipper's FIRMWARE_RESTART with a new printer.cfg): unhomed, job state gone.
    // Throw std::logic_error on another machine.
    DeltaParams delta_printer_firmware() const;
    void restart_delta_printer(const DeltaParams& firmware, double klipper_probe_z_offset_mm = 0);
    // Where the machine's work zero (G54) is now, in its machine coordinates.
    Vec3 machine_work_zero_mm() const;
    // The same for a cartesian printer (Klipper's restart leaves no skew in force), and the skew
    // Klipper's SET_SKEW or SKEW_PROFILE LOAD puts in force.
    CartesianFirmware cartesian_printer_firmware() const;
    void restart_cartesian_printer(const CartesianFirmware& firmware);
    void set_cartesian_skew(double xy_skew);
    // The machine ageing between cycles (a scanner's mirror mount creeping, a gantry's belt
    // stretching): `change` edits the scenario's hidden errors, and the machine is made again
    // from them as a power cycle makes it. The judge judges the changed machine.
    void change_machine(const std::function<void(Scenario&)>& change);

    // What the camera sees now: the printed material, or a board, rendered with the scenario's
    // camera and photo settings; `frame` varies the sensor noise. An exposure or gain `asked`
    // for scales the light (a white surface gives the scenario's exposure_dn at its exposure_us
    // and gain 1); unset, the scenario's.
    GrayImage photograph(std::uint64_t frame, const hal::CaptureRequest& asked = {}) const;
    // The camera's photo of a sheet of stock `thickness_mm` thick lying on the bed (nothing else
    // on it), at the scenario's light: the scenario's [placement].
    GrayImage photograph_sheet(const StockSheet& sheet, double thickness_mm) const {
        return photograph_sheet(sheet, thickness_mm, photo_settings_of(scenario_, InView::bed));
    }
    GrayImage photograph_sheet(const StockSheet& sheet, double thickness_mm,
                               const PhotoSettings& photo) const;
    // The camera's photo of a printed card lying on the bed, its top `thickness_mm` up: the
    // drawing's cut line (0.4 mm of ink) and its marks, at the scenario's light: the scenario's
    // print-and-cut [placement].
    GrayImage photograph_card(const PrintedCard& card, double thickness_mm) const {
        return photograph_card(card, thickness_mm, photo_settings_of(scenario_, InView::bed));
    }
    GrayImage photograph_card(const PrintedCard& card, double thickness_mm,
                              const PhotoSettings& photo) const;

    // The operator's hands.
    // The boards are the scenario's [setup] ones.
    static constexpr int kCalibrationViews = 12;
    void hold_calibration_board(int view);  // 0 .. kCalibrationViews-1, in front of the camera
    void lay_plane_board_on_bed();          // face up on the bed, clear of the printable area
    void take_board_away();
    void clear_bed();  // the printed material removed
    // A knock on the camera's mount: it turns by `turn_deg` about its own x axis (the image's
    // rows move) and shifts by `shift_mm`, and stays so.
    void knock_camera(double turn_deg, const Vec3& shift_mm);
    // The fixed reference marks on the bed (the scenario's [setup], or one near each corner of
    // the camera's view).
    const std::vector<ReferenceMark>& reference_marks() const { return reference_marks_; }

    // The judge, in the twin's truth (never called by the box's side): the delta printer as its
    // firmware is set now, over the printable area.
    DeltaJudgement judge_delta_printer() const;
    // A cartesian printer as its firmware is set now: a fresh job half a pitch off the target's,
    // as commanded and (with `correct`) through the correction the box keeps.
    RouterVerdict judge_cartesian_printer(const jobs::Correction* correct) const;
    // A galvo scanner: a fresh 30 x 30 grid of marks over `area_mm` (min x, min y, max x, max y)
    // commanded through `command_for` (the identity before a correction).
    GalvoJudgement judge_galvo_scanner(const std::function<Vec2(Vec2)>& command_for,
                                       const std::array<double, 4>& area_mm) const;

  private:
    void store_settings() const;
    void replace_printer(std::unique_ptr<MachineTwin> machine);
    void remake_printer();       // under the mutex: from the scenario, the stored settings kept
    Pose bed_to_camera() const;  // under the mutex
    mutable std::mutex mutex_;
    Scenario scenario_;
    std::filesystem::path settings_file_;
    std::unique_ptr<MachineTwin> machine_;
    std::unique_ptr<GcodeRunner> runner_;
    std::size_t strokes_cleared_ = 0;          // runner strokes before this index are off the bed
    std::vector<StrokeSegment> earlier_runs_;  // material laid before the last reset
    struct Board {
        std::string spec;
        Pose board_to_camera;
        bool on_bed = false;  // the plane's board: the reference marks show around it
    };
    std::optional<Board> board_;
    std::vector<Pose> calibration_poses_;
    std::vector<ReferenceMark> reference_marks_;
    Pose knock_;  // the camera's frame after its knocks, from the one set up: identity at first
};

// What the twin machine's firmware says when its board starts: Marlin's "start" and version,
// grbl's welcome line; nothing from RepRapFirmware (native USB: no reset, no banner).
std::vector<std::string> start_up_banner(const models::MachineFile& machine);
// grbl's "$#" and its kin, however the host numbered it: a line with no G-code word.
bool is_grbl_system_command(std::string_view line);

// The printer end of a pseudo-terminal: a thread answering as Marlin does (line numbers and
// checksums checked, Resend on a mismatch, ok per line, M503 reports), with the scenario's
// faults injected.
class TwinPrinterLink {
  public:
    explicit TwinPrinterLink(std::shared_ptr<TwinBench> bench);
    TwinPrinterLink(const TwinPrinterLink&) = delete;
    TwinPrinterLink& operator=(const TwinPrinterLink&) = delete;
    ~TwinPrinterLink();  // stops the thread and closes the master (the box sees a hang-up)
    const std::string& device_path() const { return device_path_; }
    std::size_t lines_received() const { return lines_received_; }
    // Everything the box sent has been answered: nothing unread at the printer's end of the pty,
    // no line being answered. A test on a simulated clock moves time on only then, so that the
    // printer's thread being slow on a loaded machine is not taken for a printer gone silent.
    bool settled() const;

  private:
    void serve();
    std::vector<std::string> answer(std::string line);
    std::vector<std::string> answer_as_grbl(const std::string& line);
    std::shared_ptr<TwinBench> bench_;
    int master_fd_ = -1;
    std::string device_path_;
    std::atomic<bool> stop_{false};
    std::atomic<std::size_t> lines_received_{0};
    std::atomic<bool> answering_{false};  // from reading the box's bytes to writing the replies
    long last_line_ = 0;
    bool halted_ = false;
    bool alarm_ = false;  // grbl: locked out after an alarm, until the board resets
    std::mt19937_64 noise_;
    std::thread thread_;
};

// Renders on a thread; completion on an eventfd.
class TwinCamera final : public hal::Camera {
  public:
    explicit TwinCamera(std::shared_ptr<TwinBench> bench);
    void start_capture(const hal::CaptureRequest& request) override;
    int completion_fd() const override { return capture_.fd(); }
    hal::CaptureResult take_frames() override;
    int captures_started() const { return captures_; }

  private:
    std::shared_ptr<TwinBench> bench_;
    int captures_ = 0;
    std::uint64_t frames_taken_ = 0;
    hal::BackgroundJob<hal::CaptureResult> capture_;  // last: joined before the rest goes
};

// The button pressed by whoever drives the sim (--auto, the console, a test); LEDs and the light
// remembered, the light's changes reported to `log`.
class SimLines final : public hal::Lines {
  public:
    using Log = hal::Log;
    SimLines(hal::Clock& clock, Log log);
    int button_fd() const override { return edges_.fd(); }
    std::optional<hal::ButtonEvent> read_button() override;
    void set_led(hal::Led which, bool on) override;
    void set_light(bool on) override;

    void press(std::chrono::milliseconds held);  // a press and its release, `held` apart
    bool led(hal::Led which) const { return leds_[static_cast<std::size_t>(which)]; }
    bool light() const { return light_; }

  private:
    hal::Clock& clock_;
    Log log_;
    hal::Notifier edges_;
    std::mutex mutex_;
    std::vector<hal::ButtonEvent> pending_;
    std::array<bool, 3> leds_{};
    bool light_ = false;
};

// Each frame shown becomes display/NNNN.png under the data directory.
class PngDisplay final : public hal::Display {
  public:
    explicit PngDisplay(std::filesystem::path directory);
    int width_px() const override { return 128; }
    int height_px() const override { return 64; }
    void show(const hal::MonoBitmap& frame) override;
    int frames_shown() const { return frames_; }

  private:
    std::filesystem::path directory_;
    int frames_ = 0;
};

// In the data directory: the twin printer's stored settings (its EEPROM), the G-code that
// sets them.
constexpr const char* kTwinSettingsFile = "twin-printer-settings.gcode";
// In the data directory: a twin host's disk (printer.cfg, uploaded jobs) and its API key as the
// box's key_file holds it.
constexpr const char* kTwinHostDirectory = "twin-host";
constexpr const char* kTwinHostKeyFile = "twin-host.key";
// ... and, for a host serving https ([twin] host_tls), the certificate it made, for the box's
// ca_file.
constexpr const char* kTwinHostCertificateFile = "twin-host-ca.pem";

struct SimSettings {
    std::string scenario_path;
    std::filesystem::path data_dir;  // the display's PNGs go under it
    int baud = 115200;
};

// The board's devices, as every board gives them; the sim-only parts (the bench, the printer's
// end of the link, the lines to press) stay reachable for the operator, the judge and tests.
struct SimBoard {
    std::shared_ptr<TwinBench> bench;
    std::unique_ptr<TwinPrinterLink> printer;           // a printer on a serial link: its pty's end
    std::unique_ptr<TwinHostServer> host;               // a printer behind a host: the host
    std::unique_ptr<drivers::TlsTerminator> tls_front;  // in front of it, serving https
    // The scenario's machine file as the box is given it: a host's [link] pointed at the twin's
    // address and key file.
    models::MachineFile machine;
    board::Devices devices;  // the machine's serial link: the box's end of the printer's pty
    // The devices' own, by their types.
    TwinCamera* camera = nullptr;
    SimLines* lines = nullptr;
    PngDisplay* display = nullptr;
};

// Throws ScenarioError for a scenario the sim board cannot run (no camera, not a delta).
SimBoard make_sim_board(const SimSettings& settings, hal::Clock& clock, const SimLines::Log& log);

}  // namespace calbox::sim
