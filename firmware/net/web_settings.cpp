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
    {{"tls_listen",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "serve the page over TLS (https) at HOST:PORT; the plain `listen` port, if any, then only "
      "redirects there and never takes the password; empty: no TLS"},
     [](const WebSettings& s) { return s.tls_listen; },
     [](WebSettings& s, const KeyInfo&, std::string_view t) {
         s.tls_listen = host_port(t, false);
     }},
    {{"tls_cert",
      K::text,
      {},
      0,
      0,
      {},
      true,
      "the page's certificate (PEM, the chain with the box's first); empty: a self-signed one the "
      "box makes on its first start and keeps in its data directory (web-tls.crt)"},
     [](const WebSettings& s) { return s.tls_cert; },
     [](WebSettings& s, const KeyInfo&, std::string_view t) { s.tls_cert = one_line(t); }},
    {{"tls_key", K::text, {}, 0, 0, {}, true, "the certificate's private key (PEM), with tls_cert"},
     [](const WebSettings& s) { return s.tls_key; },
     [](WebSettings& s, const KeyInfo&, std::string_view t) { s.tls_key = one_line(t); }},
};

void check_web(const WebSettings& s) {
    if (s.tls_cert.empty() != s.tls_key.empty())
        throw ConfigError(
            "web.tls_cert and web.tls_key go together: both, or neither (a "
            "self-signed certificate)");
}

}  // namespace

SettingsTable<WebSettings> web_settings_table() {
    return {"web", kWebKeys, check_web};
}

}  // namespace calbox::firmware
