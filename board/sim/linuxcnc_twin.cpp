#include "board/sim/linuxcnc_twin.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "board/sim/gcode_runner.hpp"
#include "board/sim/sim_board.hpp"
#include "core/gcode/gcode_line.hpp"

namespace calbox::sim {
namespace {

std::string upper_of(std::string text) {
    for (auto& c : text) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return text;
}

std::vector<std::string> words_of(const std::string& line) {
    std::istringstream in(line);
    std::vector<std::string> words;
    for (std::string w; in >> w;) words.push_back(w);
    return words;
}

// "set mdi G0 X1" -> "G0 X1": the rest of the line, as linuxcncrsh hands it to the interpreter.
std::string rest_after_second_word(const std::string& line) {
    std::size_t at = 0;
    for (int word = 0; word < 2; ++word) {
        at = line.find_first_not_of(" \t", at);
        at = at == std::string::npos ? line.size() : line.find_first_of(" \t", at);
        if (at == std::string::npos) return {};
    }
    const auto start = line.find_first_not_of(" \t", at);
    return start == std::string::npos ? std::string() : line.substr(start);
}

// One connection's state, as linuxcncrsh keeps it per client.
struct Client {
    bool linked = false;
    bool echo = true;
    bool verbose = false;
    bool enabled = false;
};

}  // namespace

struct LinuxCncTwin::State {
    std::shared_ptr<TwinBench> bench;
    std::string connect_password, enable_password;
    HostFaults faults;
    int listen_fd = -1;
    int port = 0;
    std::atomic<bool> stopping{false};
    std::atomic<int> connections{0};
    // The controller's, across connections (LinuxCNC's task state).
    std::string mode = "MANUAL";
    bool program_in_inches = false;
    std::string last_error;
    int mdi_lines = 0;
    std::thread thread;

    void serve() {
        while (!stopping) {
            pollfd p{listen_fd, POLLIN, 0};
            if (::poll(&p, 1, 100) <= 0) continue;
            const int fd = ::accept(listen_fd, nullptr, nullptr);
            if (fd < 0) continue;
            ++connections;
            talk(fd);
            ::close(fd);
        }
    }

    void talk(int fd) {
        Client client;
        std::string pending;
        while (!stopping) {
            pollfd p{fd, POLLIN, 0};
            if (::poll(&p, 1, 100) <= 0) continue;
            char chunk[1600];
            const ssize_t n = ::recv(fd, chunk, sizeof chunk, 0);
            if (n <= 0) return;
            if (client.echo && client.linked) write_all(fd, std::string(chunk, n));
            pending.append(chunk, static_cast<std::size_t>(n));
            std::size_t end;
            while ((end = pending.find_first_of("\r\n")) != std::string::npos) {
                const std::string line = pending.substr(0, end);
                pending.erase(0, end + 1);
                const auto words = words_of(line);
                if (words.empty()) continue;
                if (upper_of(words.front()) == "QUIT") return;
                const std::string reply = answer(client, line);
                if (!reply.empty()) write_all(fd, reply);
            }
        }
    }

    static void write_all(int fd, const std::string& text) {
        std::size_t sent = 0;
        while (sent < text.size()) {
            const ssize_t n = ::send(fd, text.data() + sent, text.size() - sent, MSG_NOSIGNAL);
            if (n <= 0) return;
            sent += static_cast<std::size_t>(n);
        }
    }

    std::string answer(Client& client, const std::string& line) {
        const auto words = words_of(line);
        const std::string command = upper_of(words.front());
        if (command == "HELLO") {
            if (words.size() < 4 || words[1] != connect_password) return "HELLO NAK\r\n";
            client.linked = true;
            return "HELLO ACK EMCNETSVR 1.1\r\n";
        }
        if (command == "SET") {
            if (!client.linked || words.size() < 2) return "SET NAK\r\n";
            return set(client, line, words);
        }
        if (command == "GET") {
            if (words.size() < 2) return "GET NAK\r\n";
            return get(words) + "\r\n";
        }
        return {};
    }

    std::string set(Client& client, const std::string& line, const std::vector<std::string>& w) {
        const std::string what = upper_of(w[1]);
        const std::string arg = w.size() > 2 ? upper_of(w[2]) : std::string();
        const auto ack = [&] {
            return client.verbose ? "SET " + what + " ACK\r\n" : std::string();
        };
        std::string nak = "SET " + what + " NAK\r\n";
        if (what == "ECHO" || what == "VERBOSE") {
            if (arg != "ON" && arg != "OFF") return nak;
            (what == "ECHO" ? client.echo : client.verbose) = arg == "ON";
            return ack();
        }
        if (what == "ENABLE") {
            if (w.size() > 2 && w[2] == enable_password) {
                client.enabled = true;
                return ack();
            }
            return nak;
        }
        // Everything else is control: the enabled connection's only.
        if (!client.enabled) return nak;
        if (what == "MODE") {
            if (arg != "MDI" && arg != "MANUAL" && arg != "AUTO") return nak;
            mode = arg;
            return ack();
        }
        if (what == "WAIT_MODE") return arg == "DONE" || arg == "RECEIVED" ? ack() : nak;
        if (what == "LINEAR_UNIT_CONVERSION") return arg == "MM" ? ack() : nak;
        if (what == "ABORT") return ack();
        if (what == "MDI") return mdi(rest_after_second_word(line)) ? ack() : nak;
        return nak;
    }

    // Runs the line on the bench; false (and the error kept) when the controller refuses it.
    bool mdi(const std::string& line) {
        if (faults.printer_not_ready) {
            last_error = "can't do that (EMC_TASK_PLAN_EXECUTE) in state OFF";
            return false;
        }
        if (mode != "MDI") {
            last_error = "Can't issue MDI command when not in MDI mode";
            return false;
        }
        ++mdi_lines;
        if (faults.silent_at_request > 0 && mdi_lines >= faults.silent_at_request) {
            while (!stopping) std::this_thread::sleep_for(std::chrono::milliseconds(20));
            return false;
        }
        try {
            const auto parsed = gcode::parse_line(line);
            // LinuxCNC's MDI runs no program end, and says nothing of why.
            if (parsed.is('M', 2) || parsed.is('M', 30)) return false;
            // The units are the interpreter's own state; the bench's machine reads millimetres.
            if ((parsed.is('G', 20) || parsed.is('G', 21)) && parsed.parameters.empty()) {
                program_in_inches = parsed.is('G', 20);
                return true;
            }
            if (program_in_inches) {
                last_error = "the twin runs no move in inches";
                return false;
            }
            (void)bench->run_printer_line(line);
        } catch (const std::exception& e) {
            last_error = e.what();
            return false;
        }
        return true;
    }

    std::string get(const std::vector<std::string>& w) {
        const std::string what = upper_of(w[1]);
        if (what == "MACHINE") return faults.printer_not_ready ? "MACHINE OFF" : "MACHINE ON";
        if (what == "MODE") return "MODE " + mode;
        if (what == "ERROR") {
            const std::string error = last_error.empty() ? "OK" : last_error;
            last_error.clear();
            return "ERROR " + error;
        }
        if (what == "PROGRAM_UNITS")
            return std::string("PROGRAM_UNITS ") + (program_in_inches ? "INCH" : "MM");
        if (what == "POS_OFFSET" && w.size() > 2) {
            const std::string axis = upper_of(w[2]);
            const Vec3 zero = bench->machine_work_zero_mm();
            const double mm = axis == "X" ? zero.x : axis == "Y" ? zero.y : zero.z;
            if (axis != "X" && axis != "Y" && axis != "Z") return "GET POS_OFFSET NAK";
            char text[64];
            std::snprintf(text, sizeof text, "POS_OFFSET %s %f", axis.c_str(), mm);
            return text;
        }
        return "GET " + what + " NAK";
    }
};

LinuxCncTwin::LinuxCncTwin(std::shared_ptr<TwinBench> bench, const std::string& passwords,
                           HostFaults faults)
    : state_(std::make_unique<State>()) {
    auto& s = *state_;
    s.bench = std::move(bench);
    const auto words = words_of(passwords);
    if (words.size() != 2)
        throw std::invalid_argument("the LinuxCNC twin takes a connect and an enable password");
    s.connect_password = words[0];
    s.enable_password = words[1];
    // A box with a wrong key file: the controller's passwords are others.
    if (faults.wrong_key) s.connect_password += "-other";
    s.faults = std::move(faults);
    s.listen_fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t size = sizeof address;
    if (s.listen_fd < 0 ||
        ::bind(s.listen_fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
        ::listen(s.listen_fd, 4) != 0 ||
        ::getsockname(s.listen_fd, reinterpret_cast<sockaddr*>(&address), &size) != 0) {
        if (s.listen_fd >= 0) ::close(s.listen_fd);
        throw std::runtime_error("the LinuxCNC twin cannot listen on loopback");
    }
    s.port = ntohs(address.sin_port);
    s.thread = std::thread([&s] { s.serve(); });
}

LinuxCncTwin::~LinuxCncTwin() {
    state_->stopping = true;
    state_->thread.join();
    ::close(state_->listen_fd);
}

std::string LinuxCncTwin::url() const {
    return "127.0.0.1:" + std::to_string(state_->port);
}

int LinuxCncTwin::connections() const {
    return state_->connections;
}

}  // namespace calbox::sim
