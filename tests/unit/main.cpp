#include <CppUTest/CommandLineTestRunner.h>
#include <CppUTest/MemoryLeakWarningPlugin.h>

#include "tests/unit/crash_report.hpp"

int main(int argc, char** argv) {
    // Libraries such as OpenCV allocate caches on first use, which CppUTest's per-test leak
    // accounting would report; the asan preset's LeakSanitizer checks for real leaks instead.
    calbox::test::report_crashes();
    MemoryLeakWarningPlugin::turnOffNewDeleteOverloads();
    return CommandLineTestRunner::RunAllTests(argc, argv);
}
