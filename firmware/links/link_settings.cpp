// The machine link's table of the configuration: [link], over the machine file's own [link].
#include <string>

#include "core/models/link_kinds.hpp"
#include "core/net/endpoints.hpp"
#include "firmware/links/make_link.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;
using setting_text::choice;
using setting_text::one_line;

// "machine" (the machine file's [link]) and every kind the box speaks.
const std::string kLinkKindChoices = "machine|" + models::link_kind_list("|");

const SettingKey<LinkSettings> kLinkKeys[] = {
    {{"kind",
      K::choice,
      {},
      0,
      0,
      kLinkKindChoices,
      true,
      "how the box reaches the machine: machine (its machine file's [link]), its serial port, "
      "a host that owns the printer, or LinuxCNC's linuxcncrsh (docs/links.md)"},
     [](const LinkSettings& s) { return s.kind; },
     [](LinkSettings& s, const KeyInfo& k, std::string_view t) { s.kind = choice(k, t); }},
    {{"url",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "the host's address, http://HOST:PORT or https://..., or linuxcncrsh's HOST:PORT (empty: "
      "the machine file's)"},
     [](const LinkSettings& s) { return s.url; },
     [](LinkSettings& s, const KeyInfo&, std::string_view t) {
         const std::string url = one_line(t);
         if (!url.empty() && url.find("://") == std::string::npos) {
             try {
                 (void)net::parse_host_port(url, true);
             } catch (const std::invalid_argument& e) {
                 throw ConfigError(std::string(e.what()) + " (a URL, or linuxcncrsh's HOST:PORT)");
             }
         } else if (!url.empty()) {
             try {
                 (void)net::parse_url(url);
             } catch (const std::invalid_argument& e) {
                 throw ConfigError(e.what());
             }
         }
         s.url = url;
     }},
    {{"key_file",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "the file holding the host's API key, alone, or linuxcncrsh's connect and enable passwords "
      "(empty: the machine file's)"},
     [](const LinkSettings& s) { return s.key_file; },
     [](LinkSettings& s, const KeyInfo&, std::string_view t) { s.key_file = one_line(t); }},
    {{"ca_file",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "an https host's certificate authority, a PEM file (empty: the machine file's, else the "
      "system's)"},
     [](const LinkSettings& s) { return s.ca_file; },
     [](LinkSettings& s, const KeyInfo&, std::string_view t) { s.ca_file = one_line(t); }},
};

}  // namespace

models::MachineLinkSettings LinkSettings::over(const models::MachineFile& machine) const {
    models::MachineFile m = machine;
    if (kind != "machine") m.link.kind = kind;
    if (!url.empty()) m.link.url = url;
    if (!key_file.empty()) m.link.key_file = key_file;
    if (!ca_file.empty()) m.link.ca_file = ca_file;
    if (const auto why = models::link_mismatch(m); !why.empty())
        throw ConfigError("link.kind: " + why);
    return m.link;
}

SettingsTable<LinkSettings> link_settings_table() {
    return {"link", kLinkKeys};
}

}  // namespace calbox::firmware
