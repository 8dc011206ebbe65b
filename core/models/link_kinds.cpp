#include "core/models/link_kinds.hpp"

namespace calbox::models {

std::string link_kind_list(std::string_view separator, bool hosts_only) {
    return kind_names_joined(kLinkKinds, separator,
                             [&](const LinkKind& k) { return k.host || !hosts_only; });
}

std::set<std::string> link_kind_names() {
    return kind_name_set(kLinkKinds);
}

}  // namespace calbox::models
