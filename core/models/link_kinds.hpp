#pragma once
// The machine link kinds, declared once: the machine file's reader takes its choices and its
// refusals from here, the configuration its `link.kind` choices, the box's link factory
// (firmware/links/make_link.cpp) and the sim board's twins (board/sim/sim_board.cpp) one entry
// each per kind, checked at compile time against this list. A new kind: a row here, its link,
// its twin, its docs (docs/links.md) and its tests.
#include <array>
#include <set>
#include <string>
#include <string_view>

#include "core/models/kind_table.hpp"

namespace calbox::models {

struct LinkKind {
    std::string_view name;      // the machine file's [link] kind
    std::string_view firmware;  // the only firmware it serves; empty: any
    // Why another firmware is refused, before "([machine] firmware = ...)".
    std::string_view serves;
    bool host = true;  // reached over the network: url, key_file, ca_file and the timeouts
};

inline constexpr std::array<LinkKind, 5> kLinkKinds{{
    {"serial", "", "", false},
    {"moonraker", "klipper", "Moonraker serves Klipper printers"},
    {"octoprint", "marlin", "the box speaks to Marlin printers through OctoPrint"},
    {"duet", "rrf", "a Duet's web API serves RepRapFirmware"},
    {"linuxcnc", "linuxcnc", "linuxcncrsh serves LinuxCNC machines"},
}};

// The row of `name`; nullptr for none.
constexpr const LinkKind* link_kind(std::string_view name) {
    for (const auto& k : kLinkKinds)
        if (k.name == name) return &k;
    return nullptr;
}

// Whether `rows` (a table elsewhere, each row's `kind` a kind's name) holds every kind, each
// once, and nothing else: the compile-time check of a factory's or a twin's table.
template <class Rows>
constexpr bool names_every_link_kind(const Rows& rows) {
    return names_each_kind_once(kLinkKinds, rows);
}

// "serial|moonraker|..." (`separator` between), the host kinds only when `hosts_only`.
std::string link_kind_list(std::string_view separator, bool hosts_only = false);
std::set<std::string> link_kind_names();  // the machine file's choices

}  // namespace calbox::models
