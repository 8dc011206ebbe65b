#pragma once
// The box's job desk: a job compensated through the correction the box keeps, where the machine
// really is (core/modes/compensate_job). A job is a file in the data directory named
// `job-NAME.EXT` (G-code or a scanner job); the compensated one is written beside it as
// `job-NAME-compensated.EXT`. The work zero is given ("X,Y", "measured", "G55=X,Y ...") or, with
// "controller", read from the controller over the machine link (grbl's `$#`: every work system's
// zero) when the link is free. The console's `compensate` row is the desk's; the web page sends
// the same command.
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/modes/compensate_job.hpp"
#include "firmware/console/console.hpp"
#include "firmware/links/machine_link.hpp"
#include "firmware/loop/event_loop.hpp"
#include "hal/storage.hpp"

namespace calbox::firmware {

class Cycle;

struct DeskOrder {
    std::string job_name;  // job-NAME.EXT in the data directory
    // "X,Y", "measured", "controller", "G54=X,Y ...", "camera [CORNER]": the sheet the last
    // bed photo found (stock.json, firmware/console/bed_photo_desk), its corner nearest the
    // machine's zero or the one named; or "marks": the drawing's place its printed marks gave in
    // the last bed photo (marks.json).
    std::optional<std::string> work_zero;
    std::optional<std::string> found_text;  // with "camera" or "marks": that file's text
    std::string work_zero_from;             // "" for one the owner gave
    std::optional<std::string> again_because;
};

class JobDesk {
  public:
    using Notice = std::function<void(const std::string&)>;
    using Today = std::function<std::string()>;  // the wall clock's date, for the job's mark
    JobDesk(EventLoop& loop, Cycle& cycle, MachineLink& link, hal::Storage& data, Today today,
            Notice notice);
    JobDesk(const JobDesk&) = delete;
    JobDesk& operator=(const JobDesk&) = delete;
    // Starts the order: "" when it started (its outcome is a notice), else why not.
    std::string start(DeskOrder order);
    bool busy() const { return busy_; }
    // The console's row: `compensate JOB [ZERO ...] [again REASON ...]`.
    ConsoleCommand command();
    // The console's row `work zero ZERO [confirm]` (X,Y or camera [CORNER]): grbl's G54 set there
    // (G10 L2 P1) only with confirm, when the link is free, then read back ($#); without confirm,
    // what would be sent.
    ConsoleCommand zero_command();

  private:
    void compensate(const DeskOrder& order, std::string result_text, std::string job_text);
    // The order placed at the work offsets grbl reports ($#), asked when the link is free.
    std::string start_from_controller(const DeskOrder& order, std::string kept, std::string job);
    // `work zero ... confirm`: refused while the link is busy; the controller's units checked
    // first where it tells them.
    void send_confirmed_work_zero(geometry::Point2 zero);
    // ZERO's machine point and where it came from, for the message; throws ConsoleRefused.
    std::pair<geometry::Point2, std::string> work_zero_of(const std::string& spec) const;
    // Sends the zero and reads it back, the outcome a notice; busy_ until then.
    void send_work_zero(geometry::Point2 zero);
    Cycle& cycle_;
    MachineLink& link_;
    hal::Storage& data_;
    Today today_;
    Notice notice_;
    Worker worker_;
    bool busy_ = false;
};

// The sheet and the printed marks the last bed photo found, kept in the data directory.
constexpr const char* kFoundStockFile = "stock.json";
constexpr const char* kFoundMarksFile = "marks.json";

// For a work zero "camera [CORNER]": the corner's name ("nearest" when none is named); nothing
// for another work zero.
std::optional<std::string> camera_corner_of(const std::string& work_zero);

// One "X,Y" word as a point (millimetres), or nothing for anything else.
std::optional<geometry::Point2> one_xy_of(const std::string& word);

// Whether machine X,Y `at` lies within the travel the machine file states (false when it states
// none): the box sends the controller no point beyond it.
bool inside_stated_travel(const models::MachineFile& machine, geometry::Point2 at);

// The file a work zero places the job by (stock.json for "camera [CORNER]", marks.json for
// "marks"), or nothing for one given in numbers or read from the controller.
std::optional<std::string> found_file_for(const std::string& work_zero);

// A desk's work zero into `request` ("" leaves it unset): "camera [CORNER]" places the job at
// the sheet the last bed photo found, "marks" by the printed marks it found (`found_text`, that
// file's text: found_file_for); throws modes::JobError when there is none.
void set_desk_work_zero(modes::JobRequest& request, const std::string& work_zero,
                        const std::optional<std::string>& found_text);

// `job-NAME.EXT` -> `job-NAME-compensated.EXT`; "" when the name is not a job's.
std::string compensated_job_name(const std::string& job_name);

}  // namespace calbox::firmware
