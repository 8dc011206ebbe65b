#include "firmware/console/job_desk.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>

#include "core/modes/compensate_job.hpp"
#include "core/modes/planar.hpp"
#include "core/modes/stock.hpp"
#include "core/modes/stock_top.hpp"
#include "core/modes/work_zero_link.hpp"
#include "core/number_text.hpp"
#include "firmware/cycle/cycle.hpp"

namespace calbox::firmware {
namespace {

constexpr std::array<const char*, 7> kJobExtensions = {".gcode", ".nc",  ".ngc", ".tap",
                                                       ".g",     ".csv", ".txt"};

// grbl's `$#`: every work system's zero it reports, as --work-zero's entries.
std::optional<std::string> work_zeros_reported(const std::vector<std::string>& replies) {
    std::string spec;
    for (const char* system : {"G54", "G55", "G56", "G57", "G58", "G59"}) {
        const auto zero = modes::grbl_work_zero_of(replies, system);
        if (!zero) continue;
        if (!spec.empty()) spec += ' ';
        spec += std::string(system) + "=" + number_text("%.3f", zero->x) + "," +
                number_text("%.3f", zero->y);
    }
    if (spec.empty()) return std::nullopt;
    return spec;
}

}  // namespace

std::optional<std::string> camera_corner_of(const std::string& work_zero) {
    if (work_zero != "camera" && work_zero.rfind("camera ", 0) != 0) return std::nullopt;
    const auto corner = work_zero.find_first_not_of(' ', 6);
    return corner == std::string::npos ? std::string("nearest") : work_zero.substr(corner);
}

namespace {

// Why a job cannot be placed by `file` (stock.json or marks.json): the last bed photo found none.
std::string nothing_found(const std::string& file) {
    return file == kFoundStockFile
               ? "no sheet found on the bed: take a bed photo with the sheet in view (bed photo), "
                 "or give the job's zero as X,Y"
               : "no printed marks found on the bed: take a bed photo with the marks in view (bed "
                 "photo marks X,Y X,Y X,Y [X,Y]), or give the job's zero as X,Y";
}

}  // namespace

std::optional<std::string> found_file_for(const std::string& work_zero) {
    if (camera_corner_of(work_zero)) return std::string(kFoundStockFile);
    if (work_zero == "marks") return std::string(kFoundMarksFile);
    return std::nullopt;
}

void set_desk_work_zero(modes::JobRequest& request, const std::string& work_zero,
                        const std::optional<std::string>& found_text) {
    if (work_zero.empty()) return;
    if (work_zero == "marks") {
        // The printed marks' fit is the job's frame: no work zero besides it.
        if (!found_text) throw modes::JobError(nothing_found(kFoundMarksFile));
        request.registration_text = found_text;
        request.registration_name = kFoundMarksFile;
        return;
    }
    request.work_zero = work_zero;
    const auto corner = camera_corner_of(work_zero);
    if (!corner) return;
    if (!found_text) throw modes::JobError(nothing_found(kFoundStockFile));
    request.work_zero = "camera";
    request.stock_text = found_text;
    request.stock_name = kFoundStockFile;
    request.stock_corner = *corner;
}

std::optional<geometry::Point2> one_xy_of(const std::string& word) {
    try {
        const auto zeros = modes::parse_work_zero(word, {});
        if (zeros[0] && std::count_if(zeros.begin(), zeros.end(),
                                      [](const auto& z) { return z.has_value(); }) == 1)
            return zeros[0];
    } catch (const std::exception&) {
    }
    return std::nullopt;
}

bool inside_stated_travel(const models::MachineFile& machine, geometry::Point2 at) {
    return machine.travel_min_x_mm && machine.travel_max_x_mm && machine.travel_min_y_mm &&
           machine.travel_max_y_mm && at.x >= *machine.travel_min_x_mm &&
           at.x <= *machine.travel_max_x_mm && at.y >= *machine.travel_min_y_mm &&
           at.y <= *machine.travel_max_y_mm;
}

// `compensate JOB [ZERO ...] [again REASON ...]`'s order; throws ConsoleRefused.
static DeskOrder desk_order_of(const std::vector<std::string>& words) {
    if (words.size() < 2)
        throw ConsoleRefused(
            "usage: compensate JOB [WORK_ZERO] [again REASON] (WORK_ZERO: X,Y, "
            "measured, controller, G54=X,Y G55=X,Y ..., camera [CORNER] or marks)");
    DeskOrder order;
    order.job_name = words[1];
    std::string zero, because;
    bool in_reason = false;
    for (std::size_t i = 2; i < words.size(); ++i) {
        if (words[i] == "--json") continue;
        if (!in_reason && words[i] == "again") {
            in_reason = true;
            continue;
        }
        std::string& into = in_reason ? because : zero;
        into += (into.empty() ? "" : " ") + words[i];
    }
    if (in_reason && because.empty()) throw ConsoleRefused("compensate: again needs the reason");
    if (!zero.empty()) order.work_zero = zero;
    if (in_reason) order.again_because = because;
    return order;
}

std::string compensated_job_name(const std::string& job_name) {
    if (job_name.rfind("job-", 0) != 0 || job_name.size() > 100 ||
        job_name.find_first_not_of(
            "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-") !=
            std::string::npos)
        return {};
    for (const char* ext : kJobExtensions) {
        const std::string e(ext);
        if (job_name.size() > e.size() + 4 &&
            job_name.compare(job_name.size() - e.size(), e.size(), e) == 0)
            return job_name.substr(0, job_name.size() - e.size()) + "-compensated" + e;
    }
    return {};
}

JobDesk::JobDesk(EventLoop& loop, Cycle& cycle, MachineLink& link, hal::Storage& data, Today today,
                 Notice notice)
    : cycle_(cycle),
      link_(link),
      data_(data),
      today_(std::move(today)),
      notice_(std::move(notice)),
      worker_(loop) {}

std::string JobDesk::start(DeskOrder order) {
    const std::string out = compensated_job_name(order.job_name);
    if (out.empty())
        return "compensate: '" + order.job_name +
               "' is not a job's name: put the job in the data directory as job-NAME.gcode (or "
               ".nc, .ngc, .tap, .g, .csv, .txt)";
    if (busy_) return "compensate: already compensating a job";
    const auto kept = cycle_.mode().kept_result_text();
    if (!kept)
        return "compensate: no correction in force: the box keeps none for this machine yet "
               "(calibrate it first)";
    std::optional<std::string> job;
    try {
        job = data_.read_file(order.job_name);
    } catch (const std::exception& e) {
        return "compensate: " + order.job_name + ": " + e.what();
    }
    if (!job) return "compensate: no " + order.job_name + " in the data directory";
    const auto& machine = cycle_.machine();
    // A controller that tells its work offsets is asked; another's job needs its zero given.
    if (!order.work_zero && machine.firmware == "grbl") order.work_zero = "controller";
    if (!order.work_zero && machine.jobs_at_work_zero())
        return "compensate: a " + machine.kind +
               "'s job is written around its work zero, which calbox cannot see (its " +
               machine.firmware +
               " does not report it over the link): give X,Y (its machine coordinates) or "
               "measured (the frame the correction was measured in)";
    if (const auto found = order.work_zero ? found_file_for(*order.work_zero) : std::nullopt) {
        order.found_text = data_.read_file(*found);
        if (!order.found_text) return "compensate: " + nothing_found(*found);
    }
    if (order.work_zero == "controller") return start_from_controller(order, *kept, *job);
    busy_ = true;
    compensate(order, *kept, *job);
    return {};
}

std::string JobDesk::start_from_controller(const DeskOrder& order, std::string kept,
                                           std::string job) {
    if (cycle_.machine().firmware != "grbl")
        return "compensate: the controller's work offsets are read from grbl ($#); this "
               "machine's firmware is " +
               cycle_.machine().firmware + ": give X,Y or measured";
    if (cycle_.state() != CycleState::idle || link_.busy())
        return "compensate: the machine link is busy with the cycle: try again when it is "
               "idle, or give the work zero";
    busy_ = true;
    link_.send_commands({"$#"}, [this, order, kept = std::move(kept),
                                 job = std::move(job)](const JobOutcome& outcome) {
        auto o = order;
        const auto spec = outcome.ok ? work_zeros_reported(outcome.replies) : std::nullopt;
        if (!spec) {
            busy_ = false;
            notice_("compensate: " + o.job_name +
                    ": the controller did not report its work offsets ($#)" +
                    (outcome.ok ? std::string() : ": " + outcome.error) + "; nothing written");
            return;
        }
        o.work_zero = *spec;
        o.work_zero_from = "the controller's work offsets ($#: " + *spec + ")";
        compensate(o, kept, job);
    });
    return {};
}

void JobDesk::compensate(const DeskOrder& order, std::string result_text, std::string job_text) {
    auto request = std::make_shared<modes::JobRequest>();
    request->result_text = std::move(result_text);
    request->result_name = "the correction in force";
    request->job_text = std::move(job_text);
    request->job_name = order.job_name;
    set_desk_work_zero(*request, order.work_zero.value_or(""), order.found_text);
    request->work_zero_from = order.work_zero_from;
    request->again_because = order.again_because;
    request->date = today_();
    auto done = std::make_shared<modes::CompensatedJob>();
    worker_.start([request, done] { *done = modes::compensate_job(*request); },
                  [this, order, done](const std::exception_ptr& error) {
                      busy_ = false;
                      const std::string out = compensated_job_name(order.job_name);
                      try {
                          if (error) std::rethrow_exception(error);
                          data_.replace_file(out, done->text);
                      } catch (const std::exception& e) {
                          notice_(std::string("compensate: ") + e.what() + "; nothing written");
                          return;
                      }
                      notice_("compensate: " + out + ": " + done->summary + "; " +
                              done->frame_line +
                              (done->held_line.empty() ? std::string() : "; " + done->held_line));
                  });
}

ConsoleCommand JobDesk::command() {
    return {"compensate", "compensate JOB [WORK_ZERO] [again REASON]",
            "a job in the data directory (job-NAME.EXT) through the correction in force, placed "
            "at its work zero (X,Y, measured, controller, G54=X,Y ..., camera [CORNER]: the "
            "sheet the last bed photo found, or marks: by the printed marks it found); written "
            "as job-NAME-compensated.EXT",
            [this](const std::vector<std::string>& words, std::string_view, ConsoleReply& reply) {
                const DeskOrder order = desk_order_of(words);
                const std::string refused = start(order);
                if (!refused.empty()) throw ConsoleRefused(refused);
                reply.text = "compensating " + order.job_name + " -> " +
                             compensated_job_name(order.job_name);
                reply.data = {{"job", order.job_name},
                              {"output", compensated_job_name(order.job_name)}};
            }};
}

ConsoleCommand JobDesk::zero_command() {
    return {"work zero", "work zero ZERO [confirm]",
            "the controller's G54 zero at ZERO: machine X,Y, or camera [CORNER] (the corner of the "
            "sheet the last bed photo found): shown first, sent (G10 L2 P1: grbl's, LinuxCNC's by "
            "MDI) only with confirm, then read back",
            [this](const std::vector<std::string>& words, std::string_view, ConsoleReply& reply) {
                const auto [given, confirmed] = words_and_confirm(words, 2);
                std::string spec;
                for (const auto& w : given) spec += (spec.empty() ? "" : " ") + w;
                if (spec.empty())
                    throw ConsoleRefused(
                        "usage: work zero ZERO [confirm] (ZERO: X,Y or camera [CORNER])");
                const auto& machine = cycle_.machine();
                if (!modes::sets_work_zero(machine.firmware))
                    throw ConsoleRefused(
                        "work zero: the box sets G54 on grbl and LinuxCNC (G10 L2 P1, read back); "
                        "this machine's firmware is " +
                        machine.firmware + ": set it on the controller");
                const auto placed = work_zero_of(spec);
                const geometry::Point2 zero = placed.first;
                const std::string& from = placed.second;
                // Bounds first: a zero beyond the travel would send every job off the machine.
                if (!inside_stated_travel(machine, zero))
                    throw ConsoleRefused("work zero: machine " + modes::machine_xy_text(zero) +
                                         " is beyond the machine file's travel (or it gives none)");
                const std::string command = modes::work_zero_command(zero);
                reply.data = {{"command", command}, {"sent", confirmed}};
                if (!confirmed) {
                    reply.text = "would send '" + command + "' (G54's zero at " + from +
                                 "): say it again with confirm";
                    return;
                }
                send_confirmed_work_zero(zero);
                reply.text = "sending '" + command + "'";
            }};
}

std::pair<geometry::Point2, std::string> JobDesk::work_zero_of(const std::string& spec) const {
    try {
        if (const auto corner = camera_corner_of(spec)) {
            const auto text = data_.read_file(kFoundStockFile);
            if (!text)
                throw ConsoleRefused(
                    "work zero: no sheet found on the bed: take a bed "
                    "photo with the sheet in view (bed photo)");
            const auto found = modes::stock_from_json(*text, kFoundStockFile);
            const auto& c = modes::stock_corner(found.stock, *corner);
            return {c.machine_mm, std::string(kFoundStockFile) + "'s " + c.name + " corner"};
        }
        const auto given_zero = one_xy_of(spec);
        if (!given_zero)
            throw ConsoleRefused("work zero '" + spec +
                                 "': give X,Y (G54's zero in machine coordinates) "
                                 "or camera [CORNER]");
        return {*given_zero, "X,Y as given"};
    } catch (const ConsoleRefused&) {
        throw;
    } catch (const std::exception& e) {
        throw ConsoleRefused("work zero: " + std::string(e.what()));
    }
}

void JobDesk::send_confirmed_work_zero(geometry::Point2 zero) {
    if (busy_ || cycle_.state() != CycleState::idle || link_.busy())
        throw ConsoleRefused("work zero: the machine link is busy: try again when the box is idle");
    busy_ = true;
    const std::string& firmware = cycle_.machine().firmware;
    const auto units = modes::work_zero_units_query(firmware);
    if (units.empty()) return send_work_zero(zero);
    // The zero is in millimetres: a controller set to inches would put it 25.4 times as far.
    link_.send_commands(units, [this, zero](const JobOutcome& outcome) {
        const std::string refused =
            outcome.ok ? modes::work_zero_units_refusal(cycle_.machine().firmware, outcome.replies)
                       : outcome.error;
        if (!refused.empty()) {
            busy_ = false;
            notice_("work zero: nothing sent: " + refused);
            return;
        }
        send_work_zero(zero);
    });
}

void JobDesk::send_work_zero(geometry::Point2 zero) {
    const std::string firmware = cycle_.machine().firmware;
    const std::string command = modes::work_zero_command(zero);
    link_.send_commands(modes::work_zero_exchange(firmware, zero), [this, command, zero, firmware](
                                                                       const JobOutcome& outcome) {
        busy_ = false;
        if (!outcome.ok) {
            notice_("work zero: '" + command + "' failed: " + outcome.error);
            return;
        }
        const auto read = modes::work_zero_read_back(firmware, outcome.replies);
        const std::string report = modes::work_zero_report_name(firmware);
        if (!read || std::abs(read->x - zero.x) > 0.0015 || std::abs(read->y - zero.y) > 0.0015)
            notice_("work zero: sent '" + command + "', but the controller reports G54 " +
                    (read ? "at machine " + modes::machine_xy_text(*read)
                          : "nowhere (" + report + " gave none)") +
                    ": check it before running a job");
        else
            notice_("work zero: the controller's G54 zero at machine " +
                    modes::machine_xy_text(zero) + " (sent '" + command + "', read back by " +
                    report + ")");
    });
}

}  // namespace calbox::firmware
