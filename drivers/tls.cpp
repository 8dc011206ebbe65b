#include "drivers/tls.hpp"

#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509v3.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/stream_traits.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <cctype>
#include <condition_variable>
#include <ctime>
#include <deque>
#include <filesystem>
#include <fstream>
#include <list>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <type_traits>
#include <vector>

#include "drivers/asio_names.hpp"
#include "drivers/http_server.hpp"
#include "drivers/tcp_listener.hpp"

namespace calbox::drivers {

namespace listening {

std::unique_ptr<ssl::context> server_tls_context(const std::string& chain_pem,
                                                 const std::string& chain_from,
                                                 const std::string& key_pem,
                                                 const std::string& key_from) {
    auto context = std::make_unique<ssl::context>(ssl::context::tls_server);
    SSL_CTX_set_min_proto_version(context->native_handle(), TLS1_2_VERSION);
    boost::system::error_code ec;
    context->use_certificate_chain(net::buffer(chain_pem), ec);
    if (ec)
        throw NetworkError("TLS: " + chain_from + ": not a certificate in PEM: " + ec.message());
    context->use_private_key(net::buffer(key_pem), ssl::context::pem, ec);
    if (ec) throw NetworkError("TLS: " + key_from + ": not a private key in PEM: " + ec.message());
    if (SSL_CTX_check_private_key(context->native_handle()) != 1)
        throw NetworkError("TLS: " + key_from + " is not the key of " + chain_from);
    return context;
}

std::string pem_file_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    if (!in || !(text << in.rdbuf())) throw NetworkError("TLS: " + path + ": cannot be read");
    return text.str();
}

}  // namespace listening

using listening::Listener;
using listening::server_tls_context;

SelfSignedCertificate self_signed_certificate(const std::vector<std::string>& names,
                                              int valid_days) {
    if (names.empty() || valid_days <= 0)
        throw NetworkError("a certificate cannot be made: no name, or no days to be valid");
    // OpenSSL's objects, each freed with its own function.
    const std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(EVP_EC_gen("P-256"),
                                                                  EVP_PKEY_free);
    const std::unique_ptr<X509, decltype(&X509_free)> cert(X509_new(), X509_free);
    if (!key || !cert) throw NetworkError("a certificate cannot be made: out of memory");
    const auto fail = [](const char* what) {
        return NetworkError(std::string("a certificate cannot be made: ") + what);
    };
    std::random_device random;
    const auto serial = (static_cast<long>(random()) << 16) ^ static_cast<long>(random());
    if (X509_set_version(cert.get(), 2) != 1 ||
        ASN1_INTEGER_set(X509_get_serialNumber(cert.get()), serial & 0x7fffffffffffL) != 1 ||
        X509_gmtime_adj(X509_getm_notBefore(cert.get()), -3600) == nullptr ||
        X509_time_adj_ex(X509_getm_notAfter(cert.get()), valid_days, 0, nullptr) == nullptr ||
        X509_set_pubkey(cert.get(), key.get()) != 1)
        throw fail("its fields");
    X509_NAME* name = X509_get_subject_name(cert.get());
    if (X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC,
                                   reinterpret_cast<const unsigned char*>(names.front().c_str()),
                                   -1, -1, 0) != 1 ||
        X509_set_issuer_name(cert.get(), name) != 1)
        throw fail("its name");
    X509V3_CTX v3;
    X509V3_set_ctx_nodb(&v3);
    X509V3_set_ctx(&v3, cert.get(), cert.get(), nullptr, nullptr, 0);
    std::string alt;
    for (const auto& n : names) {
        boost::system::error_code not_an_address;
        net::ip::make_address(n, not_an_address);
        alt += (alt.empty() ? "" : ",") + std::string(not_an_address ? "DNS:" : "IP:") + n;
    }
    X509_EXTENSION* extension =
        X509V3_EXT_conf_nid(nullptr, &v3, NID_subject_alt_name, alt.c_str());
    if (extension == nullptr) throw fail("its subjectAltName");
    const int added = X509_add_ext(cert.get(), extension, -1);
    X509_EXTENSION_free(extension);
    if (added != 1 || X509_sign(cert.get(), key.get(), EVP_sha256()) == 0)
        throw fail("its signature");
    const auto pem = [](auto write) {
        const std::unique_ptr<BIO, decltype(&BIO_free)> bio(BIO_new(BIO_s_mem()), BIO_free);
        if (!bio || write(bio.get()) != 1) throw NetworkError("a certificate cannot be written");
        char* data = nullptr;
        const long size = BIO_get_mem_data(bio.get(), &data);
        return std::string(data, static_cast<std::size_t>(size));
    };
    SelfSignedCertificate out;
    out.certificate_pem = pem([&](BIO* b) { return PEM_write_bio_X509(b, cert.get()); });
    out.private_key_pem = pem([&](BIO* b) {
        return PEM_write_bio_PrivateKey(b, key.get(), nullptr, nullptr, 0, nullptr, nullptr);
    });
    return out;
}

hal::CertificateFacts certificate_facts(const hal::ServerTls& files) {
    const auto open = [](const std::string& path) {
        std::unique_ptr<BIO, decltype(&BIO_free)> bio(BIO_new_file(path.c_str(), "r"), BIO_free);
        if (!bio && !std::filesystem::exists(path))
            throw hal::CertificateMissing(path + ": not there");
        if (!bio) throw std::runtime_error(path + ": cannot be read");
        return bio;
    };
    const auto cert_bio = open(files.certificate_file);
    const std::unique_ptr<X509, decltype(&X509_free)> cert(
        PEM_read_bio_X509(cert_bio.get(), nullptr, nullptr, nullptr), X509_free);
    if (!cert) throw std::runtime_error(files.certificate_file + ": not a certificate in PEM");
    const auto key_bio = open(files.key_file);
    const std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(
        PEM_read_bio_PrivateKey(key_bio.get(), nullptr, nullptr, nullptr), EVP_PKEY_free);
    if (!key) throw std::runtime_error(files.key_file + ": not a private key in PEM");
    if (X509_check_private_key(cert.get(), key.get()) != 1)
        throw std::runtime_error(files.key_file + ": not the key of " + files.certificate_file);
    hal::CertificateFacts facts;
    std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
    unsigned int length = 0;
    if (X509_digest(cert.get(), EVP_sha256(), digest.data(), &length) != 1)
        throw std::runtime_error(files.certificate_file + ": its fingerprint cannot be taken");
    static const char* const kHex = "0123456789ABCDEF";
    for (unsigned int i = 0; i < length; ++i) {
        if (i > 0) facts.sha256_fingerprint += ':';
        facts.sha256_fingerprint += kHex[digest[i] >> 4];
        facts.sha256_fingerprint += kHex[digest[i] & 15];
    }
    std::array<char, 256> common_name{};
    if (X509_NAME_get_text_by_NID(X509_get_subject_name(cert.get()), NID_commonName,
                                  common_name.data(), static_cast<int>(common_name.size())) > 0)
        facts.subject = common_name.data();
    std::tm until{};
    if (ASN1_TIME_to_tm(X509_get0_notAfter(cert.get()), &until) != 1)
        throw std::runtime_error(files.certificate_file + ": its expiry cannot be read");
    facts.not_after_unix_s = static_cast<std::int64_t>(timegm(&until));
    return facts;
}

struct TlsTerminator::State {
    std::unique_ptr<ssl::context> tls;
    int inner_port = 0;
    std::unique_ptr<Listener> listener;  // last: its threads use the rest

    void pass_through(tcp::socket accepted);
};

// One connection on an io_context of its own: the TLS handshake, a connection to the inner
// server, then bytes both ways until either side ends.
void TlsTerminator::State::pass_through(tcp::socket accepted) {
    net::io_context own;
    boost::system::error_code ec;
    const int outer_fd = accepted.native_handle();
    tcp::socket outer(own);
    outer.assign(accepted.local_endpoint(ec).protocol(), accepted.release(ec), ec);
    ssl::stream<tcp::socket> client(std::move(outer), *tls);
    tcp::socket inner(own);
    struct Forget {
        Listener& listener;
        std::vector<int> fds;
        ~Forget() {
            for (const int fd : fds) listener.forget(fd);
        }
    } forget{*listener, {outer_fd}};
    if (ec) return;
    client.handshake(ssl::stream_base::server, ec);
    if (ec) return;
    inner.connect(
        tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(inner_port)),
        ec);
    if (ec) return;
    if (!listener->track(inner.native_handle())) return;
    forget.fds.push_back(inner.native_handle());
    std::array<char, 16384> up{}, down{};
    const auto end = [&] {
        boost::system::error_code ignored;
        client.lowest_layer().shutdown(tcp::socket::shutdown_both, ignored);
        inner.shutdown(tcp::socket::shutdown_both, ignored);
        own.stop();
    };
    std::function<void()> upstream = [&] {
        client.async_read_some(net::buffer(up), [&](boost::system::error_code e, std::size_t n) {
            if (e) return end();
            net::async_write(inner, net::buffer(up.data(), n),
                             [&](boost::system::error_code w, std::size_t) {
                                 if (w) return end();
                                 upstream();
                             });
        });
    };
    std::function<void()> downstream = [&] {
        inner.async_read_some(net::buffer(down), [&](boost::system::error_code e, std::size_t n) {
            if (e) return end();
            net::async_write(client, net::buffer(down.data(), n),
                             [&](boost::system::error_code w, std::size_t) {
                                 if (w) return end();
                                 downstream();
                             });
        });
    };
    upstream();
    downstream();
    own.run();
}

TlsTerminator::TlsTerminator(const std::string& address, int inner_port,
                             const SelfSignedCertificate& certificate)
    : state_(std::make_unique<State>()) {
    auto& s = *state_;
    s.inner_port = inner_port;
    s.tls = server_tls_context(certificate.certificate_pem, "the certificate",
                               certificate.private_key_pem, "its key");
    s.listener = std::make_unique<Listener>(address, 0);
    s.listener->start([&s](tcp::socket socket) { s.pass_through(std::move(socket)); });
}

TlsTerminator::~TlsTerminator() {
    state_->listener->stop();
}

int TlsTerminator::port() const {
    return state_->listener->port();
}

}  // namespace calbox::drivers
