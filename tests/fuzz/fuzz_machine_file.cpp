// Fuzz target: the machine file reader (TOML).
#include "core/models/machine_file.hpp"
#include "tests/fuzz/fuzz_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        calbox::models::parse_machine_file(calbox::fuzz::as_text(data, size), "fuzz.toml");
    } catch (const calbox::models::MachineFileError&) {
    }
    return 0;
}
