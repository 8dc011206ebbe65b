// Fuzz target: the camera's placement files (JSON): the stock found (calbox view stock) and a
// drawing's place from its marks (calbox view marks). The first byte chooses the reader, the
// rest is the file.
#include "core/modes/record_error.hpp"
#include "core/modes/registration.hpp"
#include "core/modes/stock.hpp"
#include "tests/fuzz/fuzz_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    const auto text = std::string(calbox::fuzz::as_text(data + 1, size - 1));
    try {
        if (data[0] % 2 == 0)
            calbox::modes::stock_from_json(text, "fuzz.json");
        else
            calbox::modes::registration_from_json(text, "fuzz.json");
    } catch (const calbox::modes::RecordError&) {
    }
    return 0;
}
