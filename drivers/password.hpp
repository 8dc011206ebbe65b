#pragma once
// hal::PasswordHasher as PBKDF2-HMAC-SHA256 through OpenSSL, in the stored form of
// core/net/http_text.hpp.
#include <string>
#include <string_view>

#include "hal/password.hpp"

namespace calbox::drivers {

class Pbkdf2Hasher final : public hal::PasswordHasher {
  public:
    // OWASP's 2023 figure for PBKDF2-HMAC-SHA256 is 600 000; a Raspberry Pi takes about 0.3 s
    // for that, paid on every request that changes state. 100 000 keeps a request near 50 ms
    // there while the flood limit caps the guesses a client gets anyway.
    static constexpr int kDefaultIterations = 100'000;
    // New hashes at `iterations` (a stored hash is checked at its own). Fewer only where the
    // cost is not the point: the console's fuzz target, which types a password thousands of
    // times a second under the sanitizers.
    explicit Pbkdf2Hasher(int iterations = kDefaultIterations);
    std::string hash(std::string_view password) override;
    bool matches(std::string_view password, std::string_view stored) override;

  private:
    int iterations_;
};

}  // namespace calbox::drivers
