#pragma once
// A scenario's [truth.*] table, as the scenario reader hands it to the machine's kind
// (board/sim/twin_kind.hpp keeps TOML out of its users).
#include "core/models/toml_reader.hpp"

namespace calbox::sim {

struct TruthTable {
    const toml::table& table;
};

}  // namespace calbox::sim
