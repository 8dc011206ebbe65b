#include "firmware/net/web_tls.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <stdexcept>

#include "core/net/endpoints.hpp"
#include "firmware/net/box_news.hpp"
#include "firmware/net/web_window.hpp"

namespace calbox::firmware {
namespace {

// The host a client asked for (the Host header without its port), if it is a plain name or
// address: a redirect never carries what a client could not have meant.
std::optional<std::string> asked_host(const hal::ServerRequest& request) {
    const auto header = request.headers.find("host");
    if (header == request.headers.end() || header->second.empty() || header->second.size() > 255)
        return std::nullopt;
    const std::string& h = header->second;
    std::string host;
    if (h.front() == '[') {
        const auto close = h.find(']');
        if (close == std::string::npos) return std::nullopt;
        host = h.substr(0, close + 1);
        if (host.find_first_not_of("[]0123456789abcdefABCDEF:.") != std::string::npos)
            return std::nullopt;
    } else {
        host = h.substr(0, h.find(':'));
        if (host.empty() ||
            host.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                   "0123456789.-") != std::string::npos)
            return std::nullopt;
    }
    return host;
}

}  // namespace

WebTlsIdentity web_tls_identity(const WebSettings& settings, const std::string& data_dir,
                                hal::Certificates& certificates, std::int64_t now_unix_s,
                                const hal::Log& log) {
    WebTlsIdentity id;
    if (!settings.tls_cert.empty()) {
        id.files = {settings.tls_cert, settings.tls_key};
        id.facts = certificates.check(id.files);
        if (id.facts.not_after_unix_s <= now_unix_s)
            log.warning("web: the certificate " + settings.tls_cert + " ended on " +
                        utc_text(id.facts.not_after_unix_s) +
                        ": browsers refuse it until it is renewed");
        return id;
    }
    id.self_signed = true;
    const std::filesystem::path dir(data_dir);
    id.files = {(dir / kSelfSignedCertificateFile).string(), (dir / kSelfSignedKeyFile).string()};
    std::string why_new;
    try {
        id.facts = certificates.check(id.files);
        if (id.facts.not_after_unix_s - now_unix_s < kRenewWithinS)
            why_new = "the last one ends on " + utc_text(id.facts.not_after_unix_s);
    } catch (const hal::CertificateMissing&) {
        why_new = "the box had none yet";  // the first start: not a file that "cannot be read"
    } catch (const std::runtime_error& e) {
        why_new = e.what();
    }
    if (why_new.empty()) return id;
    std::vector<std::string> names;
    const auto at = net::parse_host_port(settings.tls_listen, false);
    if (at.host != "0.0.0.0" && at.host != "::") names.push_back(at.host);
    certificates.make_self_signed(id.files, names, kSelfSignedValidDays);
    id.facts = certificates.check(id.files);
    log("web: the box's own certificate made anew (" + why_new + "), SHA-256 " +
        id.facts.sha256_fingerprint + ": a browser asks once to trust it");
    return id;
}

hal::ServerResponse plain_port_answer(const hal::ServerRequest& request, int tls_port) {
    const auto host = asked_host(request);
    if (request.headers.count("authorization") != 0)
        return error_answer(403,
                            "the password is not taken over plain http while the page is on https: "
                            "it crossed the network readable; ask https://" +
                                host.value_or("BOX") + ":" + std::to_string(tls_port) +
                                "/ and change it with the console's `web password`");
    if (!host) return error_answer(400, "no Host to send the client on to");
    std::string target =
        request.target.empty() || request.target.front() != '/' ? std::string("/") : request.target;
    return {308,
            "text/plain",
            "the page is on https\n",
            {{"Location", "https://" + *host + ":" + std::to_string(tls_port) + target}}};
}

std::vector<std::string> fingerprint_lines(const std::string& sha256_fingerprint) {
    std::string hex;
    for (const char c : sha256_fingerprint)
        if (std::isxdigit(static_cast<unsigned char>(c))) hex += c;
    std::vector<std::string> lines;
    for (std::size_t at = 0; at < hex.size(); at += 16) {
        std::string line;
        for (std::size_t g = at; g < std::min(hex.size(), at + 16); g += 4) {
            if (!line.empty()) line += ' ';
            line += hex.substr(g, 4);
        }
        lines.push_back(line);
    }
    return lines;
}

}  // namespace calbox::firmware
