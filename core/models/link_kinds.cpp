#include "core/models/link_kinds.hpp"

namespace calbox::models {

std::string link_kind_list(std::string_view separator, bool hosts_only) {
    std::string out;
    for (const auto& k : kLinkKinds) {
        if (hosts_only && !k.host) continue;
        if (!out.empty()) out += separator;
        out += k.name;
    }
    return out;
}

std::set<std::string> link_kind_names() {
    std::set<std::string> names;
    for (const auto& k : kLinkKinds) names.emplace(k.name);
    return names;
}

}  // namespace calbox::models
