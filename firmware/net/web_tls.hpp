#pragma once
// TLS on the box's own page (docs/network.md): the certificate it serves, the owner's files
// (web.tls_cert, web.tls_key) or a self-signed pair the box makes on its first start and keeps
// in its data directory; the plain port's answers while TLS is on (a redirect, and never the
// password); and what the console's `web tls` and the display's network screen show of it.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "hal/http.hpp"
#include "hal/log.hpp"
#include "hal/network.hpp"

namespace calbox::firmware {

struct WebSettings;

// The self-signed pair's files in the data directory, and how long a new one is valid.
inline constexpr const char* kSelfSignedCertificateFile = "web-tls.crt";
inline constexpr const char* kSelfSignedKeyFile = "web-tls.key";
inline constexpr int kSelfSignedValidDays = 3650;
// A self-signed certificate this close to its end is made anew at the start.
inline constexpr std::int64_t kRenewWithinS = 30LL * 24 * 3600;

struct WebTlsIdentity {
    hal::ServerTls files;
    hal::CertificateFacts facts;
    bool self_signed = false;
};

// The page's certificate, checked (the key is the certificate's). The self-signed pair is made
// when it is missing, does not load, or ends within kRenewWithinS (logged, with its new
// fingerprint: a browser that trusted the old one asks again). Throws std::runtime_error when
// the owner's files do not load, naming the file; an owner's certificate past its end is
// logged as a warning and served (the browser says so too).
WebTlsIdentity web_tls_identity(const WebSettings& settings, const std::string& data_dir,
                                hal::Certificates& certificates, std::int64_t now_unix_s,
                                const hal::Log& log);

// The plain port's answer while TLS is on: a request carrying a password is refused (it has
// crossed the network readable, and is not checked); anything else is sent to the same path on
// https at `tls_port` of the host it asked for (308, so that a form posts there again).
hal::ServerResponse plain_port_answer(const hal::ServerRequest& request, int tls_port);

// The fingerprint as the display's network screen shows it: four lines of 16 hex digits in
// groups of four (the colons left out).
std::vector<std::string> fingerprint_lines(const std::string& sha256_fingerprint);

}  // namespace calbox::firmware
