#include <CppUTest/TestHarness.h>
#include <poll.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "drivers/file_storage.hpp"
#include "drivers/timerfd_clock.hpp"

using namespace calbox;

namespace {
std::filesystem::path fresh_directory() {
    char pattern[] = "/tmp/calbox-storage-XXXXXX";
    const char* made = ::mkdtemp(pattern);
    if (made == nullptr) FAIL("mkdtemp failed");
    return made;
}
}  // namespace

TEST_GROUP(FileStorage) {
    std::filesystem::path dir;
    void setup() override {
        dir = fresh_directory();
    }
    void teardown() override {
        std::filesystem::remove_all(dir);
    }
};

TEST(FileStorage, replaces_whole_file_and_leaves_no_temporary) {
    drivers::FileStorage storage(dir);
    CHECK_FALSE(storage.read_file("config.toml").has_value());
    storage.replace_file("config.toml", "a = 1\n");
    storage.replace_file("config.toml", "b = 2\n");
    STRCMP_EQUAL("b = 2\n", storage.read_file("config.toml")->c_str());
    int entries = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++entries;
    CHECK_EQUAL(1, entries);
}

TEST(FileStorage, failed_replace_keeps_the_old_file) {
    drivers::FileStorage storage(dir);
    storage.replace_file("config.toml", "old\n");
    // A directory where the temporary file must go makes the write fail.
    std::filesystem::create_directory(dir / "config.toml.tmp");
    CHECK_THROWS(std::runtime_error, storage.replace_file("config.toml", "new\n"));
    STRCMP_EQUAL("old\n", storage.read_file("config.toml")->c_str());
}

TEST(FileStorage, refuses_names_that_leave_its_directory) {
    drivers::FileStorage storage(dir);
    CHECK_THROWS(std::invalid_argument, storage.replace_file("../escape", "x"));
    CHECK_THROWS(std::invalid_argument, storage.replace_file("/etc/passwd", "x"));
    CHECK_THROWS(std::invalid_argument, storage.replace_file("", "x"));
    CHECK_THROWS(std::runtime_error, drivers::FileStorage(dir / "missing"));
}

TEST_GROUP(TimerfdClock){};

TEST(TimerfdClock, timer_fd_becomes_readable_after_expiry_and_counts_it) {
    drivers::TimerfdClock clock;
    auto timer = clock.make_timer();
    CHECK_EQUAL(0u, timer->take_expirations());
    const auto before = clock.now();
    timer->arm(std::chrono::milliseconds(2), std::chrono::nanoseconds(0));
    pollfd p{timer->fd(), POLLIN, 0};
    CHECK_EQUAL(1, ::poll(&p, 1, 5000));
    CHECK(clock.now() - before >= std::chrono::milliseconds(2));
    CHECK_EQUAL(1u, timer->take_expirations());
    CHECK_EQUAL(0u, timer->take_expirations());
    CHECK_THROWS(std::invalid_argument,
                 timer->arm(std::chrono::nanoseconds(0), std::chrono::nanoseconds(0)));
}
