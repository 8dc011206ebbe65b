#pragma once
// Drivers' error paths: what a constructor or call throws, also as an unprivileged user.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <functional>
#include <string>

namespace calbox::test {

// The message the call throws, or "" when it does not.
inline std::string construction_error(const std::function<void()>& call) {
    try {
        call();
    } catch (const std::exception& e) {
        return e.what();
    }
    return "";
}

// Runs `call` in a child that has given up root (uid and gid of nobody), where the file
// modes apply; returns what it threw. The tests run as root on CI, where nothing is denied.
inline std::string error_as_unprivileged_user(const std::function<void()>& call) {
    int fds[2];
    if (::pipe(fds) != 0) return "pipe failed";
    const pid_t child = ::fork();
    if (child == 0) {
        ::close(fds[0]);
        std::string message = "setuid failed";
        if (::setgid(65534) == 0 && ::setuid(65534) == 0) message = construction_error(call);
        [[maybe_unused]] const ssize_t n = ::write(fds[1], message.data(), message.size());
        ::_exit(0);
    }
    ::close(fds[1]);
    std::string message;
    char chunk[256];
    ssize_t n;
    while ((n = ::read(fds[0], chunk, sizeof chunk)) > 0) message.append(chunk, chunk + n);
    ::close(fds[0]);
    int status = 0;
    ::waitpid(child, &status, 0);
    return message;
}

// A file only root may open (mode 0600), removed at the end of the test.
struct ScratchFile {
    std::string path;
    explicit ScratchFile(const std::string& contents) {
        char pattern[] = "/tmp/calbox-device-XXXXXX";
        const int fd = ::mkstemp(pattern);
        if (fd >= 0) {
            [[maybe_unused]] const ssize_t n = ::write(fd, contents.data(), contents.size());
            ::close(fd);
        }
        path = pattern;
    }
    ~ScratchFile() { std::remove(path.c_str()); }
    ScratchFile(const ScratchFile&) = delete;
    ScratchFile& operator=(const ScratchFile&) = delete;
};

}  // namespace calbox::test
