#include "drivers/password.hpp"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/rand.h>

#include <array>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <vector>

#include "core/net/http_text.hpp"

namespace calbox::drivers {
namespace {

constexpr std::size_t kSaltBytes = 16;
constexpr std::size_t kHashBytes = net::StoredPassword::kHashBytes;
constexpr std::size_t kMaxPasswordBytes = 256;

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

Pbkdf2Hasher::Pbkdf2Hasher(int iterations) : iterations_(iterations) {
    if (iterations < 1) throw std::invalid_argument("PBKDF2 needs at least one iteration");
}

std::string Pbkdf2Hasher::hash(std::string_view password) {
    if (password.empty()) throw std::invalid_argument("the password is empty");
    if (password.size() > kMaxPasswordBytes)
        throw std::invalid_argument("the password is longer than 256 bytes");
    std::vector<unsigned char> salt(kSaltBytes);
    if (RAND_bytes(salt.data(), static_cast<int>(salt.size())) != 1)
        throw std::runtime_error("no random bytes for the password's salt");
    const auto hash = derive(password, salt, iterations_);
    return net::StoredPassword{iterations_, std::move(salt), {hash.begin(), hash.end()}}.text();
}

bool Pbkdf2Hasher::matches(std::string_view password, std::string_view stored) {
    const auto s = net::parse_stored_password(stored);
    if (!s || password.size() > kMaxPasswordBytes) return false;
    const auto hash = derive(password, s->salt, s->iterations);
    return CRYPTO_memcmp(hash.data(), s->hash.data(), kHashBytes) == 0;
}

}  // namespace calbox::drivers
