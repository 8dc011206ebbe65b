#include "firmware/links/gcode_host.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <stdexcept>

#include "core/gcode/gcode_line.hpp"
#include "firmware/loop/event_loop.hpp"

namespace calbox::firmware {
namespace {

bool contains(const std::string& s, std::string_view what) {
    return s.find(what) != std::string::npos;
}

// The line number of "Resend: 12" or "rs N12" or "rs 12"; -1 when there is none.
long resend_number(const std::string& reply) {
    std::size_t at = reply.find_first_of("0123456789");
    if (at == std::string::npos) return -1;
    long n = -1;
    std::from_chars(reply.data() + at, reply.data() + reply.size(), n);
    return n;
}

// What grbl 1.1's commonest codes mean (its documentation's error and alarm tables).
std::string grbl_meaning(const std::string& reply) {
    const bool alarm = reply.starts_with("ALARM:");
    long code = -1;
    const std::size_t at = reply.find(':') + 1;
    std::from_chars(reply.data() + at, reply.data() + reply.size(), code);
    if (alarm) {
        switch (code) {
            case 1:
                return "grbl: a hard limit was hit";
            case 2:
                return "grbl: a move beyond the machine's travel (soft limit)";
            case 3:
                return "grbl: reset while in motion";
            default:
                return "grbl: alarm " + std::to_string(code);
        }
    }
    switch (code) {
        case 1:
            return "grbl: a word without its letter";
        case 2:
            return "grbl: a number it cannot read";
        case 9:
            return "grbl: locked out by an alarm";
        case 15:
            return "grbl: a jog beyond the travel";
        case 20:
            return "grbl: an unsupported or invalid command";
        case 22:
            return "grbl: no feed rate set";
        case 33:
            return "grbl: a move with an invalid target";
        default:
            return "grbl: error " + std::to_string(code);
    }
}

}  // namespace

// A link that is gone is no longer watched (its descriptor would stay readable).
void GcodeHost::attach(EventLoop& loop) {
    loop.watch(port_fd(), [this, &loop] {
        on_readable();
        if (!link_gone().empty()) loop.unwatch(port_fd());
    });
    loop.watch(timer_fd(), [this] { on_timer(); });
}

void GcodeHost::detach(EventLoop& loop) {
    loop.unwatch(port_fd());
    loop.unwatch(timer_fd());
}

GcodeHost::GcodeHost(hal::SerialPort& port, hal::Clock& clock, GcodeHostSettings settings, Log log)
    : port_(port), timer_(clock.make_timer()), settings_(settings), log_(std::move(log)) {
    if (settings_.window < 1) throw std::invalid_argument("the G-code window must be at least 1");
}

void GcodeHost::start_job(const std::vector<std::string>& lines,
                          std::function<void(JobOutcome)> done) {
    if (busy()) throw std::logic_error("a G-code job is already running");
    if (!gone_.empty()) {
        done(JobOutcome{false, gone_, {}, {}});
        return;
    }
    job_.clear();
    if (settings_.numbered_lines) job_.emplace_back("M110 N0");
    for (const auto& raw : lines) {
        std::string body = gcode::strip_comments(raw);
        while (!body.empty() && (body.back() == ' ' || body.back() == '\t' || body.back() == '\r'))
            body.pop_back();
        std::size_t first = 0;
        while (first < body.size() && (body[first] == ' ' || body[first] == '\t')) ++first;
        if (first < body.size()) job_.push_back(body.substr(first));
    }
    next_ = 0;
    in_flight_ = 0;
    resends_of_line_ = 0;
    last_resend_ = 0;
    paused_ = false;
    replies_.clear();
    done_ = std::move(done);
    if (!heard_from_printer_ && settings_.startup_wait.count() > 0) {
        waiting_for_startup_ = true;
        timer_->arm(settings_.startup_wait, std::chrono::nanoseconds(0));
        return;
    }
    pump();
}

void GcodeHost::pump() {
    while (busy() && !paused_ && in_flight_ < settings_.window && next_ < job_.size()) {
        write_line(settings_.numbered_lines
                       ? gcode::numbered_line(static_cast<long>(next_), job_[next_])
                       : job_[next_]);
        ++next_;
        ++in_flight_;
    }
    if (busy() && in_flight_ == 0 && next_ >= job_.size()) finish(true, "");
}

void GcodeHost::write_line(const std::string& text) {
    ++lines_written_;
    transcript_.push_back(text);
    if (transcript_.size() > settings_.transcript_lines) transcript_.pop_front();
    outgoing_ += text;
    outgoing_ += '\n';
    flush();
    arm_deadline();
}

void GcodeHost::flush() {
    while (!outgoing_.empty()) {
        const auto* bytes = reinterpret_cast<const std::uint8_t*>(outgoing_.data());
        const std::size_t n = port_.write_some({bytes, outgoing_.size()});
        if (n == 0) return;  // the rest goes when the loop comes back
        outgoing_.erase(0, n);
    }
}

void GcodeHost::arm_deadline() {
    timer_->arm(settings_.reply_timeout, std::chrono::nanoseconds(0));
}

void GcodeHost::on_readable() {
    std::array<std::uint8_t, 512> buffer{};
    try {
        while (true) {
            const std::size_t n = port_.read_some(buffer);
            if (n == 0) break;
            incoming_.append(reinterpret_cast<const char*>(buffer.data()), n);
        }
    } catch (const std::runtime_error& e) {
        // The device vanished (USB unplugged): an error state, not a crash. The owner stops
        // watching the port (link_gone()).
        gone_ = e.what();
        if (busy()) {
            finish(false, gone_);
        } else {
            log_.warning(gone_);
        }
        return;
    }
    std::size_t end;
    while ((end = incoming_.find('\n')) != std::string::npos) {
        std::string reply = incoming_.substr(0, end);
        incoming_.erase(0, end + 1);
        if (!reply.empty() && reply.back() == '\r') reply.pop_back();
        if (!reply.empty()) handle(reply);
    }
    flush();
}

void GcodeHost::handle(const std::string& reply) {
    // Marlin's "start", grbl's "Grbl 1.1h ['$' for help]": the board has reset and is ready.
    const bool banner =
        reply == "start" || reply.starts_with("start ") || reply.starts_with("Grbl ");
    heard_from_printer_ = true;
    if (waiting_for_startup_) {
        log_("printer: " + reply);
        if (banner) {
            waiting_for_startup_ = false;
            pump();
        }
        return;
    }
    if (!busy()) {
        log_("printer: " + reply);  // a banner, or the tail of a job that ended
        return;
    }
    if (reply.starts_with("ok")) {
        if (in_flight_ > 0) --in_flight_;
        arm_deadline();
        pump();
        return;
    }
    if (reply.starts_with("Resend:") || reply.starts_with("rs ")) {
        handle_resend(reply);
        return;
    }
    if (contains(reply, "busy:")) {
        arm_deadline();  // the printer is working (homing, heating): not silent
        return;
    }
    if (reply.starts_with("error:") || reply.starts_with("ALARM:")) {
        // grbl's refusal of the line it last took (error:N) or its alarm (ALARM:N, the machine
        // locked until it is cleared): the job cannot go on.
        finish(false, "the machine answered \"" + reply + "\" (" + grbl_meaning(reply) + ") to " +
                          last_sent());
        return;
    }
    if (reply.starts_with("Error:") || reply.starts_with("!!")) {
        // Transport errors come with a resend; anything else is the printer refusing or halting.
        if (contains(reply, "checksum") || contains(reply, "Line Number") ||
            contains(reply, "No Checksum") || contains(reply, "No Line Number")) {
            return;
        }
        finish(false, "the printer reported \"" + reply + "\"");
        return;
    }
    if (reply.starts_with("//action:")) {
        handle_action(reply);
        return;
    }
    if (banner) {
        finish(
            false,
            "the printer restarted mid-job (start-up banner): the job was abandoned, not resumed");
        return;
    }
    replies_.push_back(reply);
}

void GcodeHost::handle_resend(const std::string& reply) {
    const long n = resend_number(reply);
    if (n < 0 || next_ == 0) {
        finish(false, "the printer asked for a resend without a line number (\"" + reply + "\")");
        return;
    }
    // A line not sent yet: the printer lost the last one whole (an M110 it could not
    // read leaves it counting from before), so that one goes again.
    const auto line = std::min(static_cast<std::size_t>(n), next_ - 1);
    resends_of_line_ = line == last_resend_ ? resends_of_line_ + 1 : 1;
    last_resend_ = line;
    if (resends_of_line_ > settings_.max_resends_of_a_line) {
        finish(false, "line " + std::to_string(line) + " was resent " +
                          std::to_string(settings_.max_resends_of_a_line) +
                          " times: the serial link is too noisy");
        return;
    }
    next_ = line;  // the ok that follows releases the window
}

void GcodeHost::handle_action(const std::string& reply) {
    const std::string action = reply.substr(9);
    if (action.starts_with("cancel")) {
        finish(false, "the printer cancelled the job (" + reply + ")");
    } else if (action.starts_with("pause")) {
        paused_ = true;
        log_.warning("printer paused the job (" + reply + ")");
    } else if (action.starts_with("resume")) {
        paused_ = false;
        pump();
    } else {
        log_("printer: " + reply);
    }
}

void GcodeHost::on_timer() {
    if (timer_->take_expirations() == 0) return;
    if (waiting_for_startup_) {
        // No banner: a board that does not reset on connection (or one already running).
        waiting_for_startup_ = false;
        heard_from_printer_ = true;
        pump();
        return;
    }
    if (busy() && (in_flight_ > 0 || paused_)) {
        const auto seconds = std::chrono::duration<double>(settings_.reply_timeout).count();
        char why[80];
        std::snprintf(why, sizeof why, "the printer did not answer within %.0f s (", seconds);
        finish(false, why + last_sent() + ")");
    }
}

std::string GcodeHost::last_sent() const {
    if (next_ == 0) return "no line sent";
    // Numbered, the printer's own line number (job_[0] is the M110 N0); plain, counted from 1.
    const std::size_t number = settings_.numbered_lines ? next_ - 1 : next_;
    return "line " + std::to_string(number) + ": " + job_[next_ - 1];
}

void GcodeHost::cancel(const std::string& why) {
    if (busy()) finish(false, why);
}

void GcodeHost::finish(bool ok, const std::string& error) {
    timer_->disarm();
    waiting_for_startup_ = false;
    outgoing_.clear();  // nothing more goes to the printer
    JobOutcome outcome{ok, error, std::move(replies_), {}};
    replies_.clear();
    auto done = std::move(done_);
    done_ = nullptr;
    if (done) done(std::move(outcome));
}

}  // namespace calbox::firmware
