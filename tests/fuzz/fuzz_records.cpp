// Fuzz target: the delta measurements and result files (JSON). The first byte chooses the
// reader, the rest is the file.
#include "core/modes/delta_records.hpp"
#include "core/modes/record_error.hpp"
#include "tests/fuzz/fuzz_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    const auto text = calbox::fuzz::as_text(data + 1, size - 1);
    try {
        if (data[0] % 2 == 0)
            calbox::modes::measurements_from_json(text, "fuzz.json");
        else
            calbox::modes::result_from_json(text, "fuzz.json");
    } catch (const calbox::modes::RecordError&) {
    }
    return 0;
}
