// The main of a test binary that reads inputs made outside the project (CALBOX_TEST_DATA, by
// default ../shared/data beside the source tree): where they are absent the binary says so and
// exits with 77, which ctest reports as skipped (SKIP_RETURN_CODE), not passed.
#include <CppUTest/CommandLineTestRunner.h>
#include <CppUTest/MemoryLeakWarningPlugin.h>

#include <cstdio>
#include <filesystem>

#include "tests/unit/crash_report.hpp"

int main(int argc, char** argv) {
    if (!std::filesystem::is_directory(CALBOX_TEST_DATA)) {
        std::printf("skipped: the test data %s is not here (set CALBOX_TEST_DATA)\n",
                    CALBOX_TEST_DATA);
        return 77;
    }
    calbox::test::report_crashes();
    MemoryLeakWarningPlugin::turnOffNewDeleteOverloads();
    return CommandLineTestRunner::RunAllTests(argc, argv);
}
