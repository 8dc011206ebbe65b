// Fuzz target: the console's line handler (firmware/console), with its whole table: its own rows
// and those the box's parts add (the web page's password, the job desk, OctoPrint's key). The box
// is the appliance on the sim board (tests/scenarios/delta_cycle_small.toml: the main job's delta
// at a quarter of its photo's pixels; its data and configuration in a fresh temporary folder),
// made once; its loop is not run, so what a row starts stays started.
// Each input is one typed line. One that begins with a row's name and a tab ("config set\tKEY
// VALUE") is that row's words and what follows the tab, so that a seed names its command and a
// row added to the table leaves every seed its own; any other input is the line as typed.
// A line may be refused, in one line; an exception out of reply_to, a crash or the box ending is
// a bug.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "board/devices.hpp"
#include "drivers/password.hpp"
#include "firmware/app/box_config.hpp"
#include "firmware/app/sim_appliance.hpp"
#include "firmware/console/console.hpp"
#include "firmware/console/job_desk.hpp"
#include "firmware/console/link_key.hpp"
#include "firmware/net/web_password.hpp"
#include "tests/fuzz/fuzz_target.hpp"
#include "tests/support/fake_clock.hpp"

namespace {

using namespace calbox;

struct FuzzedBox {
    std::filesystem::path dir;
    test::FakeClock clock;
    firmware::SimAppliance box;
    std::unique_ptr<hal::Storage> config_home;
    firmware::BoxConfig config;
    firmware::LogBook log_book{64};
    // The box's own hasher at the fewest PBKDF2 iterations a stored password may have (1000): the
    // row's checks and files are the same, and a password typed costs a hundredth of the box's
    // (under the sanitizers' allocator, about a second each at 100 000).
    drivers::Pbkdf2Hasher cheap_hasher{1000};
    firmware::LinkKeyRequest link_key;
    firmware::JobDesk job_desk;
    firmware::Console console;

    explicit FuzzedBox(std::filesystem::path where)
        : dir(std::move(where)),
          box({std::string(CALBOX_SOURCE_DIR) + "/tests/scenarios/delta_cycle_small.toml",
               dir / "data", 115200},
              clock, {}, {}, [](const std::string&) {}),
          config_home(board::data_directory(dir / "config")),
          link_key(
              box.loop, box.board.machine.link, box.board.devices.network->http(),
              [this] { return board::data_directory(dir / "config"); }, [](const std::string&) {}),
          job_desk(
              box.loop, box.cycle, *box.appliance.link, box.data, [] { return "2026-11-27"; },
              [](const std::string&) {}),
          console({box.cycle,
                   config,
                   *config_home,
                   "calbox.toml",
                   box.data,
                   log_book,
                   "fuzz",
                   [] {},
                   {firmware::web_password_row(config, cheap_hasher, [] {}), job_desk.command(),
                    link_key.command()}}) {}
};

FuzzedBox& fuzzed_box() {
    static FuzzedBox* made = [] {
        char folder[] = "/tmp/calbox_fuzz_console_XXXXXX";
        if (::mkdtemp(folder) == nullptr) {
            std::perror("fuzz_console: a temporary folder");
            std::abort();
        }
        std::filesystem::create_directories(std::filesystem::path(folder) / "data");
        std::filesystem::create_directories(std::filesystem::path(folder) / "config");
        return new FuzzedBox(folder);  // lives as long as the process: the twin's threads too
    }();
    return *made;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    auto& fuzzed = fuzzed_box();
    const auto& rows = fuzzed.console.rows();
    const std::string_view input = calbox::fuzz::as_text(data, size);
    std::string line(input);
    if (const auto tab = input.find('\t'); tab != std::string_view::npos) {
        const std::string_view name = input.substr(0, tab);
        if (std::any_of(rows.begin(), rows.end(), [&](const auto& r) { return r.name == name; }))
            line = std::string(name) + " " + std::string(input.substr(tab + 1));
    }
    // One line, as the console's port hands it over (its newline ends it).
    line = line.substr(0, line.find_first_of("\r\n"));
    const std::string reply = fuzzed.console.reply_to(line);
    // Every line with a word in it is answered, the answer a whole line.
    const bool has_word =
        std::any_of(line.begin(), line.end(), [](unsigned char c) { return std::isspace(c) == 0; });
    // ... in calbox's words: a library's own text (the patterns tests/cli/errors.sh looks for in
    // the command line's refusals, and nlohmann's and the standard library's) is a refusal that
    // does not say what was wrong with the line.
    for (const char* library :
         {"OpenCV(", "Assertion failed", "Premature end of JPEG", "Corrupt JPEG", "libpng",
          "[ WARN:", "[json.exception", "basic_string", "stoi", "stod", "vector::"}) {
        // (A word of the line itself, echoed in a refusal, is the user's, not the library's.)
        if (reply.find(library) != std::string::npos && line.find(library) == std::string::npos) {
            std::fprintf(stderr, "fuzz_console: \"%s\" was answered in a library's words: %s",
                         line.c_str(), reply.c_str());
            std::abort();
        }
    }
    if (has_word && (reply.empty() || reply.back() != '\n')) {
        std::fprintf(stderr, "fuzz_console: \"%s\" was answered \"%s\"\n", line.c_str(),
                     reply.c_str());
        std::abort();
    }
    return 0;
}
