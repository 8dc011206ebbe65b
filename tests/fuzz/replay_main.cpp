// The fuzz targets without libFuzzer: feeds each corpus file to the target, then a fixed number
// of seeded mutations of them (bytes flipped, inserted, deleted, runs duplicated, cut short,
// spliced with another file), so that the test suite runs every target under its own compiler
// and sanitizers. Coverage-guided fuzzing is the fuzz preset's (tests/fuzz/README.md).
//   replay CORPUS_DIR [--mutations N] [--seed S]
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "tests/fuzz/fuzz_target.hpp"

namespace {

std::vector<std::uint8_t> mutate(std::vector<std::uint8_t> bytes,
                                 const std::vector<std::vector<std::uint8_t>>& corpus,
                                 std::mt19937& random) {
    const auto pick = [&](std::size_t n) {
        return n == 0 ? 0 : std::uniform_int_distribution<std::size_t>(0, n - 1)(random);
    };
    // Bytes that matter to the readers: delimiters, signs, digits, quotes, escapes.
    static const std::string kInteresting = "[]{}()=:;,.\"'\\\n\r\t -+eE0189*#<>/&%";
    const int edits = 1 + static_cast<int>(pick(8));
    for (int e = 0; e < edits; ++e) {
        switch (pick(7)) {
            case 0:
                if (!bytes.empty())
                    bytes[pick(bytes.size())] ^= static_cast<std::uint8_t>(1u << pick(8));
                break;
            case 1:
                bytes.insert(bytes.begin() + static_cast<long>(pick(bytes.size() + 1)),
                             static_cast<std::uint8_t>(kInteresting[pick(kInteresting.size())]));
                break;
            case 2:
                if (!bytes.empty())
                    bytes.erase(bytes.begin() + static_cast<long>(pick(bytes.size())));
                break;
            case 3:
                if (!bytes.empty()) {
                    const std::size_t from = pick(bytes.size());
                    const std::size_t length =
                        1 + pick(std::min<std::size_t>(64, bytes.size() - from));
                    const std::vector<std::uint8_t> run(
                        bytes.begin() + static_cast<long>(from),
                        bytes.begin() + static_cast<long>(from + length));
                    bytes.insert(bytes.begin() + static_cast<long>(pick(bytes.size() + 1)),
                                 run.begin(), run.end());
                }
                break;
            case 4:
                bytes.resize(pick(bytes.size() + 1));
                break;
            case 5:
                if (!bytes.empty())
                    bytes[pick(bytes.size())] = static_cast<std::uint8_t>(pick(256));
                break;
            default: {
                const auto& other = corpus[pick(corpus.size())];
                if (other.empty()) break;
                const std::size_t from = pick(other.size());
                bytes.resize(pick(bytes.size() + 1));
                bytes.insert(bytes.end(), other.begin() + static_cast<long>(from), other.end());
                break;
            }
        }
    }
    return bytes;
}

// A reader that never returns is a bug as much as a crash: the input running when the watchdog
// fires is kept as hang-input (libFuzzer keeps timeout-* files), with only async-signal-safe
// calls from the handler.
const std::vector<std::uint8_t>* g_running = nullptr;
constexpr unsigned kHangSeconds = 20;

extern "C" void keep_hanging_input(int) {
    static const char kMessage[] = "an input ran past the watchdog: kept as hang-input\n";
    const int fd = ::open("hang-input", O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0 && g_running != nullptr) {
        const ssize_t written = ::write(fd, g_running->data(), g_running->size());
        (void)written;
    }
    const ssize_t said = ::write(2, kMessage, sizeof kMessage - 1);
    (void)said;
    std::_Exit(3);
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: %s CORPUS_DIR [--mutations N] [--seed S]\n", argv[0]);
        return 2;
    }
    long mutations = 0;
    unsigned seed = 1;
    for (int i = 2; i + 1 < argc; i += 2) {
        const std::string option = argv[i];
        if (option == "--mutations")
            mutations = std::atol(argv[i + 1]);
        else if (option == "--seed")
            seed = static_cast<unsigned>(std::atol(argv[i + 1]));
        else {
            std::fprintf(stderr, "unknown option %s\n", option.c_str());
            return 2;
        }
    }
    if (!std::filesystem::is_directory(argv[1])) {
        std::fprintf(stderr, "%s: not a directory\n", argv[1]);
        return 2;
    }
    std::vector<std::filesystem::path> paths;
    for (const auto& entry : std::filesystem::directory_iterator(argv[1]))
        if (entry.is_regular_file()) paths.push_back(entry.path());
    std::sort(paths.begin(), paths.end());
    std::vector<std::vector<std::uint8_t>> corpus;
    for (const auto& path : paths) {
        std::ifstream in(path, std::ios::binary);
        corpus.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    if (corpus.empty()) {
        std::fprintf(stderr, "%s: no corpus files\n", argv[1]);
        return 2;
    }
    std::signal(SIGALRM, keep_hanging_input);
    for (const auto& input : corpus) LLVMFuzzerTestOneInput(input.data(), input.size());
    std::mt19937 random(seed);
    for (long m = 0; m < mutations; ++m) {
        const auto input =
            mutate(corpus[static_cast<std::size_t>(m) % corpus.size()], corpus, random);
        g_running = &input;
        ::alarm(kHangSeconds);
        try {
            LLVMFuzzerTestOneInput(input.data(), input.size());
            ::alarm(0);
        } catch (...) {
            // Kept for the report, as libFuzzer keeps its crash-* files.
            const std::string kept = "crash-mutation-" + std::to_string(m);
            std::ofstream(kept, std::ios::binary)
                .write(reinterpret_cast<const char*>(input.data()),
                       static_cast<std::streamsize>(input.size()));
            std::fprintf(stderr, "mutation %ld escaped with an undocumented exception: %s\n", m,
                         kept.c_str());
            throw;
        }
    }
    std::printf("%zu corpus files and %ld mutations: no crash\n", corpus.size(), mutations);
    return 0;
}
