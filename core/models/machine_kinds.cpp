#include "core/models/machine_kinds.hpp"

#include <vector>

namespace calbox::models {

std::string machine_kind_list(std::string_view separator) {
    return kind_names_joined(kMachineKinds, separator, [](const MachineKind&) { return true; });
}

std::set<std::string> machine_kind_names() {
    return kind_name_set(kMachineKinds);
}

std::string family_machines(MachineFamily family) {
    std::vector<std::string_view> what;
    for (const auto& k : kMachineKinds)
        if (k.family == family) what.push_back(k.what);
    std::string out;
    for (std::size_t i = 0; i < what.size(); ++i) {
        if (i > 0) out += i + 1 == what.size() ? " and " : ", ";
        out += what[i];
    }
    return out;
}

}  // namespace calbox::models
