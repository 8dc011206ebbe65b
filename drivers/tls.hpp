#pragma once
// TLS for the servers: certificates of the box's own making and the facts of a pair in files,
// and a TLS terminator in front of a plain server (a reverse proxy before a printer's host).
#include <memory>
#include <string>
#include <vector>

#include "hal/network.hpp"

namespace calbox::drivers {

using hal::NetworkError;

// A certificate of its own making for `names` (IP addresses and host names, each in its
// subjectAltName; the first its subject), valid `valid_days` from an hour ago: PEM texts. For a
// server whose clients are given the certificate itself to trust, or check its fingerprint (the
// twin's hosts on loopback, the box's own page).
struct SelfSignedCertificate {
    std::string certificate_pem, private_key_pem;
};
SelfSignedCertificate self_signed_certificate(const std::vector<std::string>& names,
                                              int valid_days);

// The facts of a certificate and key pair in PEM files, the key checked against the certificate.
// Throws std::runtime_error naming the file and what is wrong with it.
hal::CertificateFacts certificate_facts(const hal::ServerTls& files);

// TLS on a port of `address` in front of a plain server on 127.0.0.1:`inner_port`, as a reverse
// proxy in front of a printer's host (nginx before Moonraker) serves it: each connection's bytes
// passed through both ways, a connection the inner server drops dropped too.
class TlsTerminator {
  public:
    // Port 0 takes a free one (port()). Throws NetworkError when it cannot listen or the
    // certificate does not load.
    TlsTerminator(const std::string& address, int inner_port,
                  const SelfSignedCertificate& certificate);
    TlsTerminator(const TlsTerminator&) = delete;
    TlsTerminator& operator=(const TlsTerminator&) = delete;
    ~TlsTerminator();  // closes every connection and waits for its thread
    int port() const;

  private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace calbox::drivers
