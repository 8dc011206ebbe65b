#include "board/sim/twin_host.hpp"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "board/sim/sim_board.hpp"

namespace calbox::sim {

void write_file_whole(const std::filesystem::path& path, const std::string& text) {
    const auto temporary = path.string() + ".part";
    {
        std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
        out << text;
        if (!out.flush()) throw std::runtime_error(temporary + ": cannot write");
    }
    std::filesystem::rename(temporary, path);
}

std::string read_whole_file(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error(path.string() + ": not there");
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

std::map<std::string, std::pair<std::string, std::string>> form_fields(
    const std::string& content_type, const std::string& body) {
    std::map<std::string, std::pair<std::string, std::string>> fields;
    const auto b = content_type.find("boundary=");
    if (b == std::string::npos) return fields;
    const std::string boundary = "--" + content_type.substr(b + 9);
    std::size_t at = body.find(boundary);
    while (at != std::string::npos) {
        at += boundary.size();
        if (body.compare(at, 2, "--") == 0) break;
        const auto head_end = body.find("\r\n\r\n", at);
        if (head_end == std::string::npos) break;
        const auto next = body.find("\r\n" + boundary, head_end);
        if (next == std::string::npos) break;
        const std::string head = body.substr(at, head_end - at);
        const auto quoted = [&head](const std::string& key) {
            const auto k = head.find(key + "=\"");
            if (k == std::string::npos) return std::string();
            const auto start = k + key.size() + 2;
            return head.substr(start, head.find('"', start) - start);
        };
        fields[quoted("name")] = {quoted("filename"),
                                  body.substr(head_end + 4, next - head_end - 4)};
        at = next + 2;
    }
    return fields;
}

void TwinPrint::start(const std::string& name, const std::string& job, double seconds,
                      bool cancel_half_way) {
    {
        const std::lock_guard lock(mutex_);
        if (state_ == State::printing) throw std::logic_error("Printer is already printing");
    }
    if (thread_.joinable()) thread_.join();
    std::vector<std::string> lines;
    std::istringstream in(job);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    {
        const std::lock_guard lock(mutex_);
        state_ = State::printing;
        name_ = name;
        message_.clear();
        completion_ = 0;
        ++started_;
    }
    stop_ = false;
    thread_ = std::thread([this, lines = std::move(lines), seconds, cancel_half_way] {
        using Clock = std::chrono::steady_clock;
        const auto started = Clock::now();
        const auto per_line = std::chrono::duration<double>(seconds) /
                              static_cast<double>(std::max<std::size_t>(lines.size(), 1));
        const auto set = [this](State s, double completion, std::string message = {}) {
            const std::lock_guard lock(mutex_);
            state_ = s;
            completion_ = completion;
            message_ = std::move(message);
        };
        for (std::size_t i = 0; i < lines.size(); ++i) {
            if (stop_) return;
            const double done = static_cast<double>(i) / static_cast<double>(lines.size());
            if (seconds > 0)
                std::this_thread::sleep_until(
                    started + std::chrono::duration_cast<Clock::duration>(per_line * i));
            if (cancel_half_way && i == lines.size() / 2) {
                set(State::cancelled, done);
                return;
            }
            try {
                bench_->run_printer_line(lines[i]);
            } catch (const std::exception& e) {
                set(State::error, done, e.what());
                return;
            }
            const std::lock_guard lock(mutex_);
            completion_ = done;
        }
        set(State::complete, 1.0);
    });
}

void TwinPrint::stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    const std::lock_guard lock(mutex_);
    if (state_ == State::printing) state_ = State::idle;
}

TwinPrint::State TwinPrint::state() const {
    const std::lock_guard lock(mutex_);
    return state_;
}

std::string TwinPrint::message() const {
    const std::lock_guard lock(mutex_);
    return message_;
}

std::string TwinPrint::name() const {
    const std::lock_guard lock(mutex_);
    return name_;
}

double TwinPrint::completion() const {
    const std::lock_guard lock(mutex_);
    return completion_;
}

TwinHostCore::TwinHostCore(std::shared_ptr<TwinBench> b, std::filesystem::path d,
                           TwinHostSettings settings)
    : bench(std::move(b)),
      dir(std::move(d)),
      key(std::move(settings.api_key)),
      faults(settings.faults),
      print_seconds(settings.print_seconds),
      print_radius_mm(settings.print_radius_mm),
      duet_sbc(settings.duet_sbc),
      print(std::make_unique<TwinPrint>(bench)) {
    std::filesystem::create_directories(dir);
}

bool TwinHostCore::held_silent(int n) const {
    if (faults.silent_at_request <= 0 || n < faults.silent_at_request) return false;
    while (!stopping) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    return true;
}

bool TwinHostCore::restarts_at(int n) {
    if (faults.restart_at_request <= 0 || n != faults.restart_at_request) return false;
    restart_now();
    return true;
}

void TwinHostCore::restart_now() {
    restarting_until = (std::chrono::steady_clock::now() + std::chrono::milliseconds(1500))
                           .time_since_epoch()
                           .count();
    print->stop();
    server->drop_connections();
}

bool TwinHostCore::restarting() const {
    return std::chrono::steady_clock::now().time_since_epoch().count() < restarting_until;
}

std::string TwinHostCore::url() const {
    return "http://127.0.0.1:" + std::to_string(server->port());
}

void TwinHostCore::shut_down() {
    stopping = true;
    server.reset();
    print->stop();
}

}  // namespace calbox::sim
