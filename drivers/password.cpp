#include "drivers/password.hpp"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/rand.h>

#include <array>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <vector>

namespace calbox::drivers {
namespace {

constexpr std::string_view kScheme = "pbkdf2-sha256";
// OWASP's 2023 figure for PBKDF2-HMAC-SHA256 is 600 000; a Raspberry Pi takes about 0.3 s for
// that, paid on every request that changes state. 100 000 keeps a request near 50 ms there
// while the flood limit caps the guesses a client gets anyway.
constexpr int kIterations = 100'000;
constexpr std::size_t kSaltBytes = 16;
constexpr std::size_t kHashBytes = 32;
constexpr std::size_t kMaxPasswordBytes = 256;

std::string hex(const unsigned char* bytes, std::size_t n) {
    static constexpr char digits[] = "0123456789abcdef";
    std::string out;
    out.reserve(2 * n);
    for (std::size_t i = 0; i < n; ++i) {
        out += digits[bytes[i] >> 4];
        out += digits[bytes[i] & 15];
    }
    return out;
}

std::optional<std::vector<unsigned char>> unhex(std::string_view text) {
    if (text.size() % 2 != 0) return std::nullopt;
    std::vector<unsigned char> out;
    for (std::size_t i = 0; i < text.size(); i += 2) {
        int v = 0;
        for (const char c : text.substr(i, 2)) {
            v <<= 4;
            if (c >= '0' && c <= '9')
                v |= c - '0';
            else if (c >= 'a' && c <= 'f')
                v |= c - 'a' + 10;
            else
                return std::nullopt;
        }
        out.push_back(static_cast<unsigned char>(v));
    }
    return out;
}

struct Stored {
    int iterations = 0;
    std::vector<unsigned char> salt, hash;
};

std::optional<Stored> parse(std::string_view stored) {
    std::array<std::string_view, 4> parts;
    for (std::size_t i = 0; i < parts.size(); ++i) {
        const auto colon = stored.find(':');
        if ((colon == std::string_view::npos) != (i + 1 == parts.size())) return std::nullopt;
        parts[i] = stored.substr(0, colon);
        if (colon != std::string_view::npos) stored.remove_prefix(colon + 1);
    }
    if (parts[0] != kScheme || parts[1].empty() || parts[1].size() > 7) return std::nullopt;
    Stored s;
    for (const char c : parts[1]) {
        if (c < '0' || c > '9') return std::nullopt;
        s.iterations = s.iterations * 10 + (c - '0');
    }
    auto salt = unhex(parts[2]);
    auto hash = unhex(parts[3]);
    if (s.iterations < 1000 || !salt || salt->size() < 8 || !hash || hash->size() != kHashBytes)
        return std::nullopt;
    s.salt = std::move(*salt);
    s.hash = std::move(*hash);
    return s;
}

std::array<unsigned char, kHashBytes> derive(std::string_view password,
                                             const std::vector<unsigned char>& salt,
                                             int iterations) {
    std::array<unsigned char, kHashBytes> out{};
    if (PKCS5_PBKDF2_HMAC(password.data(), static_cast<int>(password.size()), salt.data(),
                          static_cast<int>(salt.size()), iterations, EVP_sha256(),
                          static_cast<int>(out.size()), out.data()) != 1)
        throw std::runtime_error("PBKDF2 failed");
    return out;
}

}  // namespace

std::string password_hash(std::string_view password) {
    if (password.empty()) throw std::invalid_argument("the password is empty");
    if (password.size() > kMaxPasswordBytes)
        throw std::invalid_argument("the password is longer than 256 bytes");
    std::vector<unsigned char> salt(kSaltBytes);
    if (RAND_bytes(salt.data(), static_cast<int>(salt.size())) != 1)
        throw std::runtime_error("no random bytes for the password's salt");
    const auto hash = derive(password, salt, kIterations);
    return std::string(kScheme) + ":" + std::to_string(kIterations) + ":" +
           hex(salt.data(), salt.size()) + ":" + hex(hash.data(), hash.size());
}

bool password_matches(std::string_view password, std::string_view stored) {
    const auto s = parse(stored);
    if (!s || password.size() > kMaxPasswordBytes) return false;
    const auto hash = derive(password, s->salt, s->iterations);
    return CRYPTO_memcmp(hash.data(), s->hash.data(), kHashBytes) == 0;
}

bool is_password_hash(std::string_view stored) {
    return parse(stored).has_value();
}

std::optional<std::string> basic_auth_password(std::string_view value) {
    constexpr std::string_view scheme = "Basic ";
    if (value.size() <= scheme.size() || value.substr(0, scheme.size()) != scheme ||
        value.size() > 2048)
        return std::nullopt;
    value.remove_prefix(scheme.size());
    if (value.size() % 4 != 0) return std::nullopt;
    std::string decoded(value.size() / 4 * 3, '\0');
    const int n = EVP_DecodeBlock(reinterpret_cast<unsigned char*>(decoded.data()),
                                  reinterpret_cast<const unsigned char*>(value.data()),
                                  static_cast<int>(value.size()));
    if (n < 0) return std::nullopt;
    // EVP_DecodeBlock counts the padding's zero bytes in: take them off.
    std::size_t length = static_cast<std::size_t>(n);
    for (std::size_t pad = 0; pad < 2 && !value.empty() && value[value.size() - 1 - pad] == '=';
         ++pad)
        --length;
    decoded.resize(length);
    const auto colon = decoded.find(':');
    if (colon == std::string::npos) return std::nullopt;
    return decoded.substr(colon + 1);
}

}  // namespace calbox::drivers
