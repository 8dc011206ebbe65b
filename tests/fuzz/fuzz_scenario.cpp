// Fuzz target: the twin's scenario file (TOML), read from a file as the sim board reads it.
#include <unistd.h>

#include <fstream>

#include "board/sim/scenario.hpp"
#include "tests/fuzz/fuzz_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const std::string path =
        "/tmp/calbox-fuzz-scenario-" + std::to_string(::getpid()) + ".toml";
    std::ofstream(path, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    try {
        calbox::sim::load_scenario(path);
    } catch (const calbox::sim::ScenarioError&) {
    }
    return 0;
}
