// The twin's printer end of a pseudo-terminal (TwinPrinterLink, board/sim/sim_board.hpp): the
// machine's firmware as a host hears it over a serial line.
#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <thread>

#include "board/sim/gcode_runner.hpp"
#include "board/sim/sim_board.hpp"
#include "core/gcode/gcode_line.hpp"
#include "drivers/termios_port.hpp"

namespace calbox::sim {
namespace {

bool sets_delta_settings(const std::string& text) {
    try {
        const gcode::Line line = gcode::parse_line(text);
        return (line.is('M', 665) || line.is('M', 666)) && !line.parameters.empty();
    } catch (const gcode::SyntaxError&) {
        return false;  // the printer's own reading reports it
    }
}

}  // namespace

// grbl's "$#" and its kin, however the host numbered it: no G-code word.
bool is_grbl_system_command(std::string_view line) {
    try {
        return gcode::strip_comments(gcode::without_checksum(line)).find('$') != std::string::npos;
    } catch (const gcode::SyntaxError&) {
        return false;  // the printer's own reading reports it
    }
}

std::vector<std::string> start_up_banner(const models::MachineFile& machine) {
    if (machine.firmware == "marlin") return {"start", "echo:Marlin 2.1.2 (calbox twin)"};
    if (machine.firmware == "grbl") return {"Grbl 1.1h ['$' for help]"};
    return {};
}

namespace {

std::string as_lines(const std::vector<std::string>& lines) {
    std::string text;
    for (const auto& line : lines) text += line + "\n";
    return text;
}

}  // namespace

TwinPrinterLink::TwinPrinterLink(std::shared_ptr<TwinBench> bench)
    : bench_(std::move(bench)), noise_(bench_->scenario().photo.seed * 31 + 17) {
    master_fd_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (master_fd_ < 0 || ::grantpt(master_fd_) != 0 || ::unlockpt(master_fd_) != 0)
        throw std::runtime_error(std::string("cannot make a pseudo-terminal: ") +
                                 std::strerror(errno));
    // Raw from birth: a new pty echoes and edits lines until its slave is configured, so the
    // start-up banner, written before the box's driver has opened the line, came back to the
    // printer as input ("start" read as a G-code line) when the box was slow to open it.
    termios line{};
    const bool got = ::tcgetattr(master_fd_, &line) == 0;
    if (got) ::cfmakeraw(&line);
    if (!got || ::tcsetattr(master_fd_, TCSANOW, &line) != 0)
        throw std::runtime_error(std::string("cannot make the pseudo-terminal raw: ") +
                                 std::strerror(errno));
    device_path_ = ::ptsname(master_fd_);
    ::fcntl(master_fd_, F_SETFL, ::fcntl(master_fd_, F_GETFL) | O_NONBLOCK);
    thread_ = std::thread([this] { serve(); });
}

TwinPrinterLink::~TwinPrinterLink() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    ::close(master_fd_);
}

void TwinPrinterLink::serve() {
    std::string incoming;
    std::string outgoing = as_lines(start_up_banner(bench_->scenario().machine));
    char buffer[4096];
    while (!stop_) {
        pollfd p{master_fd_, static_cast<short>(POLLIN | (outgoing.empty() ? 0 : POLLOUT)), 0};
        const int ready = ::poll(&p, 1, 20);
        if (ready <= 0) continue;
        if ((p.revents & POLLHUP) != 0 && (p.revents & POLLIN) == 0) {
            // Nobody holds the other end yet (or any more): wait for the box to open it.
            ::usleep(10000);
            continue;
        }
        if ((p.revents & POLLIN) != 0) {
            answering_ = true;  // before the read empties the pty: one of the two always shows
            const ssize_t n = ::read(master_fd_, buffer, sizeof buffer);
            if (n > 0) incoming.append(buffer, static_cast<std::size_t>(n));
        }
        std::size_t end;
        while ((end = incoming.find('\n')) != std::string::npos) {
            std::string line = incoming.substr(0, end);
            incoming.erase(0, end + 1);
            if (!line.empty() && line.back() == '\r') line.pop_back();
            if (line.empty()) continue;
            for (const auto& reply : answer(std::move(line))) outgoing += reply + "\n";
        }
        while (!outgoing.empty()) {
            const ssize_t n = ::write(master_fd_, outgoing.data(), outgoing.size());
            if (n <= 0) break;
            outgoing.erase(0, static_cast<std::size_t>(n));
        }
        answering_ = !outgoing.empty();
    }
}

bool TwinPrinterLink::settled() const {
    int unread = 0;
    if (::ioctl(master_fd_, FIONREAD, &unread) != 0) return true;  // closed: nothing to wait for
    return unread == 0 && !answering_;
}

std::vector<std::string> TwinPrinterLink::answer(std::string line) {
    const auto& faults = bench_->scenario().faults;
    const std::size_t count = ++lines_received_;
    if (halted_) return {};
    if (faults.silent_after_lines > 0 &&
        count > static_cast<std::size_t>(faults.silent_after_lines))
        return {};
    if (faults.reset_at_line > 0 && count == static_cast<std::size_t>(faults.reset_at_line)) {
        bench_->reset_printer();
        last_line_ = 0;
        alarm_ = false;
        return start_up_banner(bench_->scenario().machine);
    }
    if (bench_->scenario().machine.firmware == "grbl") return answer_as_grbl(line);
    // Line noise: one bit of the command flipped in transit; the checksum catches it.
    const std::size_t star = line.find('*');
    const std::size_t space = line.find(' ');
    if (faults.line_noise > 0 && star != std::string::npos && space != std::string::npos &&
        space + 1 < star &&
        std::uniform_real_distribution<double>(0, 1)(noise_) < faults.line_noise) {
        const std::size_t at = space + 1 + noise_() % (star - space - 1);
        line[at] = static_cast<char>(line[at] ^ (1 << (noise_() % 7)));
    }
    const auto resend = [&](const std::string& why) {
        return std::vector<std::string>{
            "Error:" + why + ", Last Line: " + std::to_string(last_line_),
            "Resend: " + std::to_string(last_line_ + 1), "ok"};
    };
    if (!line.empty() && line[0] == 'N') {
        if (star == std::string::npos) return resend("No Checksum with line number");
        const std::string body = line.substr(0, star);
        const long n = std::strtol(line.c_str() + 1, nullptr, 10);
        if (std::to_string(gcode::checksum(body)) != line.substr(star + 1))
            return resend("checksum mismatch");
        if (body.find("M110") != std::string::npos) {
            last_line_ = n;
            return {"ok"};
        }
        if (n != last_line_ + 1) return resend("Line Number is not Last Line Number+1");
        last_line_ = n;
    }
    if (faults.error_at_line > 0 && count == static_cast<std::size_t>(faults.error_at_line)) {
        halted_ = true;
        return {"Error:Printer halted. kill() called!"};
    }
    // Settings acknowledged but not applied; asking for them still answers.
    if (faults.settings_ignored && sets_delta_settings(line)) return {"ok"};
    std::vector<std::string> replies;
    try {
        replies = bench_->run_printer_line(line);
    } catch (const std::exception& e) {
        return {std::string("Error:") + e.what(), "ok"};
    }
    replies.emplace_back("ok");
    return replies;
}

// grbl 1.1 reads plain lines: a checksum's `*` is a word without its letter (error:1), M110 a
// command it does not have (error:20). A line it refuses is answered by error:N alone, a move
// beyond the travel by its soft-limit alarm, after which every line is locked out (error:9).
std::vector<std::string> TwinPrinterLink::answer_as_grbl(const std::string& line) {
    const auto& faults = bench_->scenario().faults;
    if (alarm_) return {"error:9"};
    if (line.find('*') != std::string::npos) return {"error:1"};
    if (!is_grbl_system_command(line)) {
        // grbl's M codes: program stops and ends, the spindle (laser), coolant, parking.
        constexpr std::array<int, 11> kGrblM = {0, 1, 2, 3, 4, 5, 7, 8, 9, 30, 56};
        try {
            const gcode::Line parsed = gcode::parse_line(line);
            if (parsed.command_letter == 'M' &&
                std::find(kGrblM.begin(), kGrblM.end(), parsed.command_number) == kGrblM.end())
                return {"error:20"};
        } catch (const gcode::SyntaxError&) {
            return {"error:1"};
        }
    }
    if (faults.error_at_line > 0 &&
        lines_received_ == static_cast<std::size_t>(faults.error_at_line)) {
        alarm_ = true;
        return {"ALARM:1"};  // a hard limit switch
    }
    std::vector<std::string> replies;
    try {
        replies = bench_->run_printer_line(line);
    } catch (const JobMachineError& e) {
        alarm_ = true;
        return {"ALARM:" + std::to_string(e.grbl_alarm)};
    } catch (const std::exception&) {
        return {"error:20"};
    }
    replies.emplace_back("ok");
    return replies;
}

}  // namespace calbox::sim
