#pragma once
// The bed as it is now (docs/placing.md): the console's `bed photo` row has the camera take a
// frame while the box is idle and projects it onto the machine's coordinates through the planar
// correction in force and the set-up's camera and plane, kept in the data directory as
// bed-view.png with its world file bed-view.pgw; the web page's Place screen shows the newest.
// The surface seen is the machine file's, or the stock's top the owner gives. With `marks`, a
// printed drawing's registration marks are found in the same photo and the drawing's place kept
// as marks.json, which `compensate JOB marks` places a job by (print and cut).
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "core/modes/registration.hpp"
#include "firmware/console/console.hpp"
#include "firmware/cycle/cycle.hpp"
#include "firmware/loop/event_loop.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

struct BedPhoto;

class BedPhotoDesk {
  public:
    using Notice = std::function<void(const std::string&)>;
    BedPhotoDesk(EventLoop& loop, Cycle& cycle, hal::Storage& data, Notice notice);
    BedPhotoDesk(const BedPhotoDesk&) = delete;
    BedPhotoDesk& operator=(const BedPhotoDesk&) = delete;
    ~BedPhotoDesk();
    // The console's row: `bed photo [SURFACE_MM] [marks X,Y X,Y X,Y [X,Y] [diameter MM]]`.
    ConsoleCommand command();

  private:
    struct Order;
    // "" when the camera was asked for a frame (the outcome is a notice), else why not.
    std::string start(std::optional<double> surface_height_mm,
                      std::optional<modes::RegistrationRequest> marks);
    void on_frame(const hal::Frame& frame);
    // What the worker makes of one photo: its files, the sheet and the marks found (or why not).
    struct Developed;
    static void develop(const Order& order, const BedPhoto& photo, Developed& developed);
    // The files kept: the view, its world file, and the sheet and marks of this photo or none.
    void keep(const Order& order, const Developed& developed);
    static std::string notice_of(const Order& order, const Developed& developed);
    std::pair<double, std::string> surface_height(std::optional<double> given,
                                                  const models::MachineFile& machine);

    Cycle& cycle_;
    hal::Storage& data_;
    Notice notice_;
    std::unique_ptr<Order> waiting_;  // for the camera's next frame
    Worker worker_;
    CycleSubscription news_;
};

}  // namespace calbox::firmware
