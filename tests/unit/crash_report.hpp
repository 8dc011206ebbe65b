#pragma once
// A test binary that dies on a signal says where: ctest keeps only what was written, and
// CppUTest's output to a pipe is block-buffered, so a crash lost the lines of the tests before
// it and named no place (CI once reported "SegFault" in a group of seventeen tests and nothing
// more). Output goes out line by line, and a fatal signal writes the thread's stack (glibc's
// backtrace, async-signal-safe once primed) before the default action ends the process.
#include <execinfo.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <initializer_list>

namespace calbox::test {

inline void write_stack_and_die(int signal_number) {
    const char* name = strsignal(signal_number);
    const char head[] = "\n*** test binary killed by signal: ";
    (void)!::write(STDERR_FILENO, head, sizeof head - 1);
    (void)!::write(STDERR_FILENO, name, std::strlen(name));
    (void)!::write(STDERR_FILENO, "\n", 1);
    void* frames[64];
    const int depth = ::backtrace(frames, 64);
    ::backtrace_symbols_fd(frames, depth, STDERR_FILENO);
    std::signal(signal_number, SIG_DFL);
    std::raise(signal_number);
}

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitizerReports = true;  // its own handler says more: left in place
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitizerReports = true;
#else
constexpr bool kSanitizerReports = false;
#endif
#else
constexpr bool kSanitizerReports = false;
#endif

inline void report_crashes() {
    std::setvbuf(stdout, nullptr, _IOLBF, 0);
    if (kSanitizerReports) return;
    void* prime[1];
    ::backtrace(prime, 1);  // loads libgcc now, not inside the handler
    for (const int s : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT})
        std::signal(s, write_stack_and_die);
}

}  // namespace calbox::test
