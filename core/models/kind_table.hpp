#pragma once
// What every table of kinds (link_kinds.hpp, machine_kinds.hpp) answers the same way: each row
// has a `name`; a table elsewhere (a factory's, a twin's) has one row per kind, its `kind`.
#include <cstddef>
#include <set>
#include <string>
#include <string_view>

namespace calbox::models {

// Whether `rows` holds every kind of `kinds`, each once, and nothing else: the compile-time
// check of a table that must follow the kinds.
template <class Kinds, class Rows>
constexpr bool names_each_kind_once(const Kinds& kinds, const Rows& rows) {
    if (rows.size() != kinds.size()) return false;
    for (const auto& k : kinds) {
        int found = 0;
        for (const auto& row : rows) found += row.kind == k.name ? 1 : 0;
        if (found != 1) return false;
    }
    return true;
}

// The kinds' names with `separator` between, those `keep` takes.
template <class Kinds, class Keep>
std::string kind_names_joined(const Kinds& kinds, std::string_view separator, Keep keep) {
    std::string out;
    for (const auto& k : kinds) {
        if (!keep(k)) continue;
        if (!out.empty()) out += separator;
        out += k.name;
    }
    return out;
}

template <class Kinds>
std::set<std::string> kind_name_set(const Kinds& kinds) {
    std::set<std::string> names;
    for (const auto& k : kinds) names.emplace(k.name);
    return names;
}

}  // namespace calbox::models
