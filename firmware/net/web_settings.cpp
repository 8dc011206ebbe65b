// The web page's table of the configuration: [web], where it listens and its password's hash.
#include <string>

#include "core/net/http_text.hpp"
#include "firmware/net/web_window.hpp"

namespace calbox::firmware {
namespace {

using K = ConfigKind;
using setting_text::host_port;
using setting_text::one_line;

const SettingKey<WebSettings> kWebKeys[] = {
    {{"listen",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "serve the box's web page at HOST:PORT (an IP address; 0.0.0.0 for every interface); "
      "empty: no web page"},
     [](const WebSettings& s) { return s.listen; },
     [](WebSettings& s, const KeyInfo&, std::string_view t) { s.listen = host_port(t, false); }},
    {{"password",
      K::text,
      {},
      0,
      0,
      {},
      false,
      "the web page's password, as its hash (the console's `web password` sets it); empty: the "
      "page changes nothing"},
     [](const WebSettings& s) { return s.password_hash; },
     [](WebSettings& s, const KeyInfo&, std::string_view t) {
         const std::string hash = one_line(t);
         if (!hash.empty() && !net::is_password_hash(hash))
             throw ConfigError("not a password hash: set the password with `web password`");
         s.password_hash = hash;
     }},
};

}  // namespace

SettingsTable<WebSettings> web_settings_table() {
    return {"web", kWebKeys};
}

}  // namespace calbox::firmware
