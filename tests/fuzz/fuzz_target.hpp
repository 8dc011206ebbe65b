#pragma once
// One fuzz target per reader of outside input. Each defines LLVMFuzzerTestOneInput: built with
// clang's libFuzzer in the fuzz preset, and with replay_main.cpp everywhere else (the test
// suite replays the corpus and a fixed number of seeded mutations of it).
//
// A reader may refuse its input only with the error it documents; any other exception escaping
// it is a bug (its message would not say what is wrong with the file), and aborts the run.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace calbox::fuzz {

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
    return {reinterpret_cast<const char*>(data), size};
}

}  // namespace calbox::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
